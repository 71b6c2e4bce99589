"""Issue 4's recovery acceptance on the virtual campaign, library only: clean, static k, then
the second-order PEM fit of every vehicle, compared with the declared truth."""

import pytest

from railtherm import aggregate, identify, ingest, kvalue, synth


@pytest.fixture(scope="module")
def table(campaign_study):
    root, campaign, study = campaign_study
    fits = []
    for vehicle in study.vehicles.values():
        data = vehicle.data

        def clean(name, data=data, vehicle=vehicle):
            key, _, _ = ingest.window_spec(data, name)
            return ingest.clean_window(root / vehicle.raw_files[key], data, name)

        k = kvalue.for_vehicle(clean("kvalue"), data, source=vehicle.id).to_dict()
        tables = {w["name"]: clean(w["name"]) for w in data["windows"]["identification"]}
        estimate, series = identify.identify(tables, data, k, 2)
        fits.append(identify.check(estimate, series, data["check"]))
    return aggregate.fit_table(fits, synth.ground_truth_table(campaign)).set_index("vehicle")


def test_vehicles_without_deviations_are_recovered_with_a_good_fit(table):
    clean = table[table["deviations"] == ""]
    assert len(clean) >= 6
    for vid, row in clean.iterrows():
        for p in ("C", "K_veh", "C_veh"):
            assert row[f"{p}_recovered"], (vid, p, row[f"{p}_rel_error"])
        assert row["R2"] >= 0.98, vid
        assert row["verdict"] == "fit acceptable", vid


def test_vehicles_with_deviations_are_put_in_doubt(table):
    deviating = table[table["deviations"] != ""]
    assert len(deviating) >= 4
    for vid, row in deviating.iterrows():
        assert row["verdict"] == "assumptions in doubt", vid
