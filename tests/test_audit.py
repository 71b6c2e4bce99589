"""The audit of published values: every check family on hand-built passing and failing cases,
printed-rounding arithmetic (property-based), the paper's own numbers, and the command line."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from railtherm import audit
from railtherm.audit import Interval, Printed, Published
from railtherm.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "published" / "paper.yaml"
RANGES = REPO / "config" / "audit.yaml"


@pytest.fixture(scope="module")
def ranges():
    return audit.load_ranges(RANGES)


def sheet(**sections) -> Published:
    """A small published document: two metros, consistent unless a test changes it."""
    data = {
        "document": "hand-built sheet",
        "classes": {"of": {"A1": "metro", "A2": "metro"}},
        "parameters": {
            "location": "Sheet 1",
            "units": {"k": "W/(m² K)", "C": "J/K", "K_veh": "W/K", "C_veh": "J/K", "R2": "1"},
            "rows": {
                "A1": {
                    "k": "2.5",
                    "C": "1.0×10^7",
                    "K_veh": "400",
                    "C_veh": "1.5×10^7",
                    "R2": "0.990",
                },
                "A2": {
                    "k": "2.9",
                    "C": "8.0×10^6",
                    "K_veh": "300",
                    "C_veh": "1.2×10^7",
                    "R2": "0.970",
                },
            },
        },
        "generalised": {
            "location": "Sheet 2",
            "units": {"c_veh": "J/(kg K)", "delta": "1"},
            # m_veh 37.5 t and 30 t
            "rows": {
                "A1": {"c_veh": "400", "delta": "1.5"},
                "A2": {"c_veh": "400", "delta": "1.5"},
            },
        },
    }
    for name, value in sections.items():
        data[name] = value
    return Published("sheet.yaml", data)


def edited(pub: Published, path: str, value) -> Published:
    data = copy.deepcopy(pub.data)
    *keys, last = path.split(".")
    node = data
    for key in keys:
        node = node[key]
    node[last] = value
    return Published(pub.file, data)


def severities(findings) -> list[str]:
    return [f.severity for f in findings]


# ---------------------------------------------------------------------------------------------
# Printed numbers and intervals


@pytest.mark.parametrize(
    "text, value, lo, hi",
    [
        ("2.5", 2.5, 2.45, 2.55),
        ("246", 246, 245.5, 246.5),
        ("47,831", 47831, 47830.5, 47831.5),
        ("3.0×10^7", 3.0e7, 2.95e7, 3.05e7),
        ("1.3x10^7", 1.3e7, 1.25e7, 1.35e7),
        ("7.2e5", 7.2e5, 7.15e5, 7.25e5),
        ("0.990", 0.99, 0.9895, 0.9905),
    ],
)
def test_a_printed_number_stands_for_the_interval_of_its_rounding(text, value, lo, hi):
    p = Printed.parse(text)
    assert p.value == pytest.approx(value)
    assert (p.interval.lo, p.interval.hi) == (pytest.approx(lo), pytest.approx(hi))


@pytest.mark.parametrize("text", ["", "abc", "2.5 W", "1,23", "3.0×10^", None, 2.5])
def test_what_is_not_a_printed_number_is_refused(text):
    with pytest.raises(ValueError, match="where"):
        Printed.parse(text, "where")


@given(st.integers(1, 99_999), st.integers(0, 3), st.integers(-6, 9), st.booleans())
def test_printing_any_number_of_the_interval_gives_the_same_text(mantissa, decimals, exp, sci):
    """The interval is exactly the set of values that print as the text (half-open edges)."""
    m = mantissa / 10**decimals
    text = f"{m:.{decimals}f}×10^{exp}" if sci else f"{m * 10**exp:.{max(decimals - exp, 0)}f}"
    if not sci and exp > decimals:
        return  # an integer printed without its trailing zeros being significant
    p = Printed.parse(text)
    for t in (0.01, 0.5, 0.99):
        x = p.interval.lo + t * (p.interval.hi - p.interval.lo)
        if sci:
            again = f"{x / 10**exp:.{decimals}f}×10^{exp}"
        else:
            again = f"{x:.{max(decimals - exp, 0)}f}"
        assert Printed.parse(again).value == pytest.approx(p.value, rel=1e-9)


positive = st.floats(1e-3, 1e6, allow_nan=False)


@given(positive, positive, positive, positive, st.floats(0, 1), st.floats(0, 1))
def test_interval_quotient_holds_every_quotient_of_its_points(a, b, c, d, s, t):
    x, y = Interval(min(a, b), max(a, b)), Interval(min(c, d), max(c, d))
    q = x / y
    p = (x.lo + s * (x.hi - x.lo)) / (y.lo + t * (y.hi - y.lo))
    assert q.lo * (1 - 1e-12) <= p <= q.hi * (1 + 1e-12)


@settings(max_examples=200)
@given(st.floats(1e5, 1e8), st.floats(1e5, 1e8), st.integers(1, 3), st.integers(1, 3))
def test_a_ratio_consistent_within_printed_rounding_is_never_reported(C, C_veh, sig, dec):
    """Print C and C_veh to ``sig`` significant digits and their true ratio to ``dec``
    decimals, as a table would: the audit must call the ratio consistent."""

    def sci(x):
        e = math.floor(math.log10(x))
        m = round(x / 10**e, sig - 1)
        if m >= 10:
            m, e = m / 10, e + 1
        return f"{m:.{sig - 1}f}×10^{e}"

    pub = sheet()
    pub = edited(pub, "parameters.rows.A1.C", sci(C))
    pub = edited(pub, "parameters.rows.A1.C_veh", sci(C_veh))
    pub = edited(pub, "generalised.rows.A1.delta", f"{C_veh / C:.{dec}f}")
    if C_veh / C < 10**-dec:
        return  # printed as 0.0...: no digit to compare
    (a1,) = [f for f in audit.check_delta_ratio(pub) if f.subject == "A1"]
    assert a1.severity == "info", a1.message


# ---------------------------------------------------------------------------------------------
# Consistency


def test_delta_ratio_passes_and_fails():
    ok = audit.check_delta_ratio(sheet())
    assert severities(ok) == ["info", "info"]
    assert "C_veh / C = 1.5×10^7 / 1.0×10^7 = 1.5" in ok[0].message
    bad = audit.check_delta_ratio(edited(sheet(), "generalised.rows.A2.delta", "1.9"))
    assert severities(bad) == ["info", "error"] and bad[1].subject == "A2"
    assert "stands for [1.85, 1.95]" in bad[1].message


def test_a_ratio_off_at_the_point_but_inside_the_rounding_is_consistent():
    # 1.5e7 / 1.0e7 = 1.50, but [1.45, 1.55]e7 / [0.95, 1.05]e7 = [1.381, 1.632]
    pub = edited(sheet(), "generalised.rows.A1.delta", "1.62")
    assert audit.check_delta_ratio(pub)[0].severity == "info"


def statement(**kw):
    base = {"id": "s", "location": "Text", "quantity": "c_veh", "unit": "J/(kg K)"}
    return [base | kw]


def test_stated_mean_passes_and_fails():
    good = sheet(statements=statement(statistic="mean", **{"class": "metro"}, printed="400"))
    assert severities(audit.check_statements(good)) == ["info"]
    bad = sheet(statements=statement(statistic="mean", **{"class": "metro"}, printed="410"))
    (finding,) = audit.check_statements(bad)
    assert finding.severity == "error"
    assert "(400 + 400) / 2 = 400" in finding.message


def test_stated_range_passes_and_fails():
    good = sheet(
        statements=statement(statistic="range", **{"class": "all"}, printed=["400", "400"])
    )
    assert severities(audit.check_statements(good)) == ["info"]
    bad = sheet(statements=statement(statistic="range", **{"class": "all"}, printed=["350", "400"]))
    assert severities(audit.check_statements(bad)) == ["error"]


def test_stated_order_passes_fails_and_admits_when_rounding_cannot_tell():
    pub = sheet()
    pub.data["classes"]["of"]["A2"] = "regional"
    claim = statement(statistic="increasing", quantity="delta", classes=["metro", "regional"])
    pub.data["statements"] = claim
    pub = edited(pub, "generalised.rows.A2.delta", "2.5")
    assert severities(audit.check_statements(pub)) == ["info"]
    pub = edited(pub, "generalised.rows.A2.delta", "0.5")
    assert severities(audit.check_statements(pub)) == ["error"]
    pub = edited(pub, "generalised.rows.A1.delta", "1")  # [0.5, 1.5] against [1.45, 1.55]
    pub = edited(pub, "generalised.rows.A2.delta", "1.5")
    assert severities(audit.check_statements(pub)) == ["warning"]


def counts(evaluated):
    return {
        "location": "Sheet 0",
        "columns": ["metro", "regional", "sum"],
        "rows": {"measured": ["3", "1", "4"], "evaluated": evaluated},
        "evaluated_row": "evaluated",
    }


def test_counts_pass_and_fail():
    good = audit.check_counts(sheet(counts=counts(["2", "0", "2"])))
    assert set(severities(good)) == {"info"}
    bad = audit.check_counts(sheet(counts=counts(["2", "1", "2"])))
    errors = {(f.check, f.subject) for f in bad if f.severity == "error"}
    assert errors == {("count_sum", "evaluated"), ("count_rows", "regional")}


def test_tables_listing_different_vehicles_are_inconsistent():
    pub = sheet()
    del pub.data["generalised"]["rows"]["A2"]
    (finding,) = [f for f in audit.check_counts(pub) if f.check == "same_vehicles"]
    assert finding.severity == "error" and "A2" in finding.message


# ---------------------------------------------------------------------------------------------
# Plausibility


def test_implied_mass_passes_and_fails(ranges):
    assert severities(audit.check_implied_mass(sheet(), ranges)) == ["info", "info"]
    pub = edited(sheet(), "generalised.rows.A1.c_veh", "4000")  # 1.5e7 / 4000 = 3.75 t
    finding = audit.check_implied_mass(pub, ranges)[0]
    assert finding.severity == "warning" and "= 3.75 t" in finding.message


def test_total_specific_heat_passes_and_fails(ranges):
    assert set(severities(audit.check_total_specific_heat(sheet(), ranges))) == {"info"}
    # C = 2e8 in 37.5 t: (2e8 + 1.5e7) / 37,500 = 5733 J/(kg K) > water
    pub = edited(sheet(), "parameters.rows.A1.C", "2.0×10^8")
    finding = audit.check_total_specific_heat(pub, ranges)[0]
    assert finding.severity == "error" and "5733 J/(kg K)" in finding.message


def test_printed_values_against_class_ranges(ranges):
    assert set(severities(audit.check_published_in_range(sheet(), ranges))) == {"info"}
    pub = edited(sheet(), "parameters.rows.A2.k", "9.0")
    bad = [f for f in audit.check_published_in_range(pub, ranges) if f.severity != "info"]
    assert [(f.check, f.subject) for f in bad] == [("k_range", "A2")]


def test_time_constant_passes_and_fails(ranges):
    assert set(severities(audit.check_time_constant(sheet(), ranges))) == {"info"}
    pub = edited(sheet(), "parameters.rows.A1.C", "1.0×10^4")
    pub = edited(pub, "parameters.rows.A1.C_veh", "1.0×10^4")  # minutes, not hours
    assert audit.check_time_constant(pub, ranges)[0].severity == "warning"


# ---------------------------------------------------------------------------------------------
# Fitness


def test_r2_below_the_threshold_is_unfit_as_a_reference(ranges):
    assert severities(audit.check_r2(sheet(), ranges)) == ["info", "info"]
    pub = edited(sheet(), "parameters.rows.A2.R2", "0.5")
    finding = audit.check_r2(pub, ranges)[1]
    assert finding.severity == "warning" and "50% of the variance" in finding.message
    looser = dict(ranges, r2_min=0.4)
    assert audit.check_r2(pub, looser)[1].severity == "info"


def test_a_coupling_far_above_the_loss_to_outdoors_is_not_identifiable(ranges):
    assert severities(audit.check_coupling(sheet(), ranges)) == ["info", "info"]
    pub = edited(sheet(), "parameters.rows.A1.K_veh", "90,000")
    finding = audit.check_coupling(pub, ranges)[0]
    assert finding.severity == "warning" and "not identifiable" in finding.message


# ---------------------------------------------------------------------------------------------
# Units and typography


@pytest.mark.parametrize(
    "unit, dims",
    [
        ("W/(m² K)", (1, 0, -3, -1)),
        ("W/(m^2 K)", (1, 0, -3, -1)),
        ("J/K", (1, 2, -2, -1)),
        ("J/(kg K)", (0, 2, -2, -1)),
        ("/(kg K)", (-1, 0, 0, -1)),
        ("1", (0, 0, 0, 0)),
    ],
)
def test_dimension_of_printed_units(unit, dims):
    assert audit.dimension(unit) == dims


def test_units_pass_and_fail():
    assert set(severities(audit.check_units(sheet()))) == {"info"}
    pub = edited(sheet(), "parameters.units.K_veh", "J/K")
    bad = [f for f in audit.check_units(pub) if f.severity != "info"]
    assert [f.subject for f in bad] == ["K_veh column"] and "conductance" in bad[0].message
    pub = edited(sheet(), "parameters.units.k", "W/(m² furlong)")
    bad = [f for f in audit.check_units(pub) if f.severity != "info"]
    assert "does not know" in bad[0].message


def test_mixed_thousands_separators_are_noted():
    assert audit.check_separators(sheet()) == []
    pub = edited(sheet(), "parameters.rows.A1.K_veh", "4,000")
    pub = edited(pub, "parameters.rows.A2.K_veh", "3000")
    (finding,) = audit.check_separators(pub)
    assert finding.severity == "info" and "A1 4,000" in finding.message


# ---------------------------------------------------------------------------------------------
# Reproduction


def estimates(k_lo: float, k_hi: float) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "vehicle": ["A1"],
            "k": [(k_lo + k_hi) / 2],
            "k_lo": [k_lo],
            "k_hi": [k_hi],
            "verdict": ["fit acceptable"],
            "source": ["synthetic: virtual climatic wind tunnel campaign (not measurements)"],
        }
    )


def test_reproduction_agrees_and_differs(ranges):
    (agree,) = audit.check_reproduction(sheet(), ranges, estimates(2.4, 2.6))
    assert agree.severity == "info" and "synthetic" in agree.message
    (differ,) = audit.check_reproduction(sheet(), ranges, estimates(2.6, 2.8))
    assert differ.severity == "warning" and differ.subject == "A1 k"
    assert audit.check_reproduction(sheet(), ranges, None) == []


# ---------------------------------------------------------------------------------------------
# The paper's numbers


@pytest.fixture(scope="module")
def paper_findings(ranges):
    return audit.run(
        audit.load_published(PAPER), ranges, audit.read_estimates(REPO / "results/tables")
    )


def test_the_paper_audit_finds_what_a_reader_can_verify_by_hand(paper_findings):
    f = paper_findings
    errors = set(
        zip(
            f.loc[f.severity == "error", "check"],
            f.loc[f.severity == "error", "subject"],
            strict=True,
        )
    )
    # (664 + 577 + 595 + 703) / 4 = 634.75, printed as 603; Regio1: 4.6e6 / 664 = 6.9 t,
    # (4.3e7 + 4.6e6) / 6.9 t = 6,900 J/(kg K), more than water
    assert errors == {("stated_mean", "regional_mean_c_veh"), ("total_specific_heat", "Regio1")}
    assert f.loc[f.check == "stated_mean", "severity"].tolist() == ["error", "info"]
    assert (
        f.loc[(f.check == "stated_mean") & (f.subject == "metro_mean_c_veh"), "severity"].item()
        == "info"
    )  # 371.8 -> 372
    units = f[(f.family == "units") & (f.severity == "warning")]
    assert set(units.subject) == {"c_veh column", "initial K_veh = 20"}
    unfit = set(f.loc[(f.check == "r2") & (f.severity == "warning"), "subject"])
    assert unfit == {"Metro3", "Metro4", "Regio1", "Regio3", "Main1", "Main2"}
    assert set(f.loc[(f.check == "coupling") & (f.severity == "warning"), "subject"]) == {
        "Metro3",
        "Main1",
    }
    # every delta of Table 3 is consistent with Table 2 within the printed rounding
    assert (f.loc[f.check == "delta_ratio", "severity"] == "info").all()
    assert len(f.loc[f.check == "delta_ratio"]) == 13


def test_the_paper_audit_is_honest_about_the_reproduction(paper_findings, tmp_path):
    rep = paper_findings[paper_findings.family == "reproduction"]
    assert len(rep) > 0 and rep.message.str.contains("synthetic").all()
    audit.audit(PAPER, RANGES, REPO / "results/tables", tmp_path)
    text = (tmp_path / "audit.md").read_text(encoding="utf-8")
    assert "test the method" in text.replace("tests the method", "test the method")
    assert "not the published measurements" in text


def test_findings_are_ordered_by_severity(paper_findings):
    rank = paper_findings.severity.map({"error": 0, "warning": 1, "info": 2})
    assert rank.is_monotonic_increasing


# ---------------------------------------------------------------------------------------------
# Files and the command line


def test_a_number_not_as_printed_names_file_key_and_value(tmp_path):
    data = yaml.safe_load(PAPER.read_text(encoding="utf-8"))
    data["parameters"]["rows"]["Tram1"]["C"] = "3.0 × 10 to the 7"
    path = tmp_path / "sheet.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        audit.load_published(path)
    message = str(err.value)
    assert "sheet.yaml" in message and "parameters.rows.Tram1.C" in message
    assert "3.0 × 10 to the 7" in message


def test_a_vehicle_without_class_is_refused(tmp_path):
    data = yaml.safe_load(PAPER.read_text(encoding="utf-8"))
    del data["classes"]["of"]["Main2"]
    path = tmp_path / "sheet.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    with pytest.raises(ConfigError, match="Main2"):
        audit.load_published(path)


def railtherm(*args, cwd=REPO):
    return subprocess.run(
        [sys.executable, "-m", "railtherm", *args], capture_output=True, text=True, cwd=cwd
    )


def test_cli_audits_a_data_sheet_without_the_pipeline(tmp_path):
    """A manufacturer's sheet in the same format: two vehicles, parameters only."""
    data = {
        "document": "Data sheet XY",
        "classes": {"of": {"XY1": "regional", "XY2": "regional"}},
        "parameters": {
            "location": "page 3",
            "units": {"k": "W/(m² K)", "C": "J/K", "K_veh": "J/K", "C_veh": "J/K"},
            "rows": {
                "XY1": {"k": "1.6", "C": "5.0×10^6", "K_veh": "800", "C_veh": "2.0×10^7"},
                "XY2": {"k": "1.8", "C": "6.0×10^6", "K_veh": "700", "C_veh": "2.5×10^7"},
            },
        },
    }
    path = tmp_path / "xy.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    out = tmp_path / "out"
    run = railtherm("audit", str(path), "--ranges", str(RANGES), "--out", str(out))
    assert run.returncode == 0, run.stderr
    findings = pd.read_csv(out / "findings.csv")
    assert set(findings.family) == {"plausibility", "fitness", "units"}
    assert "K_veh column" in set(findings.loc[findings.severity == "warning", "subject"])
    failing = railtherm(
        "audit", str(path), "--ranges", str(RANGES), "--out", str(out), "--fail-on", "warning"
    )
    assert failing.returncode == 1


def test_cli_on_the_paper_is_deterministic_and_fails_on_errors_when_asked(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        run = railtherm("audit", str(PAPER), "--estimates", "results/tables", "--out", str(out))
        assert run.returncode == 0, run.stderr
        assert "2 error" in run.stdout
    for name in ("findings.csv", "audit.md"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    strict = railtherm("audit", str(PAPER), "--out", str(a), "--fail-on", "error")
    assert strict.returncode == 1


def test_cli_names_a_missing_file(tmp_path):
    run = railtherm("audit", str(tmp_path / "nope.yaml"), "--out", str(tmp_path))
    assert run.returncode == 1
    assert "nope.yaml" in run.stderr and "not found" in run.stderr
    assert not (tmp_path / "findings.csv").exists()
