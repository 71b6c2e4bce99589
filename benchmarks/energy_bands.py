"""How wide the annual energy's bands are, read from the study's table.

    python benchmarks/energy_bands.py [results/tables/annual_energy.csv]

Per row of the table: the base total's band as ± half its width relative to the total, the
what-if difference's likewise relative to the difference, and the difference's band width
relative to the base total's; printed as ranges over the rows, with the unmet hours of the
base runs.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    table = pd.read_csv(args[0] if args else ROOT / "results" / "tables" / "annual_energy.csv")
    base = table[table["variant"] == "base"]
    paired = table[table["variant"] != "base"].merge(
        base, on=["vehicle", "climate"], suffixes=("", "_base")
    )
    total = 50 * (base["energy_kWh_hi"] - base["energy_kWh_lo"]) / base["energy_kWh"]
    width = paired["difference_kWh_hi"] - paired["difference_kWh_lo"]
    difference = 50 * width / paired["difference_kWh"].abs()
    ratio = width / (paired["energy_kWh_hi_base"] - paired["energy_kWh_lo_base"])
    print(f"totals' bands: ±{total.min():.1f} to ±{total.max():.1f} % of the total")
    print(f"differences' bands: ±{difference.min():.1f} to ±{difference.max():.1f} %")
    print(f"difference's band / base total's band: {ratio.min():.2f} to {ratio.max():.2f}")
    for _, row in base.iterrows():
        if row["unmet_h"] > 0:
            print(f"unmet: {row['vehicle']} in {row['climate']}: {row['unmet_h']:.0f} h a year")


if __name__ == "__main__":
    main()
