"""The study-wide data checks that `railtherm validate` and the workflow's parse share."""

from __future__ import annotations


def test_vehicles_reading_one_record_under_two_ids_are_named():
    """Two ids on the same raw files and identification windows (a vehicle added twice): a
    warning naming both, which `railtherm validate` and the workflow's parse print (before,
    the class statistics counted them as two vehicles without a word; one class band came
    out 2.08 [2.08, 2.08]). The same file cut into other windows is no such pair."""
    from types import SimpleNamespace

    from railtherm.data.datacheck import shared_records

    def vehicle(path, start):
        windows = {"identification": [{"name": "run", "start": start, "end": "2024-01-02"}]}
        return SimpleNamespace(raw_files={"run": path}, windows=windows)

    study = SimpleNamespace(
        vehicles={
            "MetroX": vehicle("data/mx.csv", "2024-01-01"),
            "Metro-Y": vehicle("data/mx.csv", "2024-01-01"),
            "MetroZ": vehicle("data/mx.csv", "2024-01-01T12:00"),  # another cut of the record
            "Tram1": vehicle("data/t1.csv", "2024-01-01"),
        }
    )
    (warning,) = shared_records(study)
    assert warning.startswith("vehicles MetroX, Metro-Y read the same raw files (data/mx.csv)")


def test_a_study_figure_the_study_cannot_draw_is_warned_of_alike(tmp_path, capsys):
    """Figure 3 of a vehicle without order 1, Figure 4 naming a misspelt id and a vehicle
    without order 2: before, the figures were silently not drawn (or drawn without the
    vehicle); `railtherm validate` and the workflow's parse now warn of each alike. The
    shipped study (Figure 3 and 4 vehicles with both orders) is warned of nothing."""
    import re

    import yaml
    from snakemake_run import make_study, snakemake

    from railtherm.cli import main

    study = make_study(tmp_path)
    assert main(["validate", "--headers-only", "-d", str(study)]) == 0
    assert "warning" not in capsys.readouterr().err
    cfg_path = study / "config" / "config.yaml"
    cfg = yaml.safe_load(cfg_path.read_text())
    cfg["study"]["figure4"] = ["Metro1", "Metro9"]
    cfg_path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    for vid, orders in (("Tram2", [2]), ("Metro1", [1])):
        path = study / "config" / "vehicles" / f"{vid}.yaml"
        data = yaml.safe_load(path.read_text())
        data["model"] = {**data.get("model", {}), "orders": orders}
        path.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", "--headers-only", "-d", str(study)]) == 0
    warned = re.findall(r"^warning: (study\.figure.*)$", capsys.readouterr().err, re.M)
    assert len(warned) == 3, warned
    assert warned[0].startswith("study.figure3 = 'Tram2': its model.orders are [2]")
    assert "'Metro1', whose model.orders [1] have no second order" in warned[1]
    assert warned[2].startswith("study.figure4 names 'Metro9', no vehicle of the study (Tram1,")
    run = snakemake(study, "--dry-run", "--quiet")
    assert run.returncode == 0, run.stderr[-2000:]
    parsed = re.findall(r"warning: (study\.figure.*)$", run.stdout + run.stderr, re.M)
    assert parsed == warned
