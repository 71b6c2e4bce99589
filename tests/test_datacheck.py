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
