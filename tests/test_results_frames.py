"""Results.to_pandas() and Results.to_xarray() (issue 33, "Results in Python"): the values are
the Results' own arrays, unchanged; every column's group, owner, quantity and unit is the
kernel's column metadata of OUT.json (read here with json, a second path), and the units
are those io/results_output.f90's walk_columns states; the scene's fingerprint is
pymr.Scene's."""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr

pd = pytest.importorskip("pandas")
xr = pytest.importorskip("xarray")

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
QUANTITIES = {"scene.t_end": 0.02, "output.quantities": ["coordinates", "markers", "reactions", "energy"]}

#: Units as walk_columns states them (fortran/io/results_output.f90), written out here.
KERNEL_UNITS = {"t": "s", "elevation.q": "rad", "elevation.qd": "rad/s", "gun.a1": "m kg^0.5",
                "gun.ad1": "m kg^0.5/s", "muzzle.x": "m", "muzzle.vz": "m/s", "elevation.fx": "N",
                "bracket.fy": "N", "traverse.mz": "N m", "energy.kinetic": "J", "energy.total": "J",
                "energy.drive_work": "J"}


@pytest.fixture(scope="module")
def tank(tmp_path_factory):
    """The tank for 20 ms with markers, reactions and energies: its Results and its OUT.json."""
    out = tmp_path_factory.mktemp("frames") / "tank.csv"
    res = pymr.run(TANK, out, overrides=QUANTITIES)
    return res, json.loads(out.with_suffix(".json").read_text()), out


def test_to_pandas_values_are_the_results_arrays(tank):
    res, _, _ = tank
    df = res.to_pandas()
    assert df.index.name == "t" and np.array_equal(df.index.to_numpy(), res.t)
    assert list(df.columns) == res.columns[1:]
    for name in res.columns[1:]:
        assert np.array_equal(df[name].to_numpy(), res[name]), name
    assert df.shape == (len(res.t), len(res.columns) - 1)


def test_to_pandas_metadata_is_the_kernels(tank):
    res, stats, _ = tank
    df = res.to_pandas()
    meta = stats["columns"]
    expected = {name: dict(zip(("group", "owner", "quantity", "unit"), fields))
                for name, *fields in zip(meta["name"], meta["group"], meta["owner"], meta["quantity"], meta["unit"])}
    assert df.attrs["columns"] == expected
    assert df.attrs["units"] == {name: e["unit"] for name, e in expected.items()}
    for name, unit in KERNEL_UNITS.items():
        assert df.attrs["units"][name] == unit, name
    assert df.attrs["columns"]["elevation.fx"] == {"group": "reactions", "owner": "elevation", "quantity": "force",
                                                   "unit": "N"}
    assert df.attrs["columns"]["energy.kinetic"]["group"] == "energy"
    assert df.attrs["fingerprint"] == pymr.Scene(TANK, QUANTITIES).fingerprint
    assert df.attrs["title"] == "tank gun-turret (Kim and Kim 2000)"
    assert df.attrs["method"] == res.method and df.attrs["method"].startswith("single")


def test_to_xarray_values_units_and_attributes(tank):
    res, stats, _ = tank
    ds = res.to_xarray()
    assert list(ds.coords) == ["t"] and np.array_equal(ds["t"].to_numpy(), res.t)
    assert ds["t"].attrs["unit"] == "s"
    assert list(ds.data_vars) == res.columns[1:]
    meta = stats["columns"]
    for k, name in enumerate(meta["name"][1:], start=1):
        var = ds[name]
        assert var.dims == ("t",) and np.array_equal(var.to_numpy(), res[name]), name
        assert var.attrs == {"unit": meta["unit"][k], "units": meta["unit"][k], "group": meta["group"][k],
                             "owner": meta["owner"][k], "quantity": meta["quantity"][k], "long_name": name}
    for name, unit in KERNEL_UNITS.items():
        assert ds[name].attrs["unit"] == unit, name
    assert ds.attrs["fingerprint"] == stats["scene_fingerprint"] == pymr.Scene(TANK, QUANTITIES).fingerprint
    assert ds.attrs["title"] == res.title and ds.attrs["method"] == res.method
    assert ds.attrs["scene"] == stats["scene"] and ds.attrs["scene"].endswith("tank_gun_turret.nml")


def test_netcdf_round_trip(tank, tmp_path):
    """Through scipy's netCDF3 writer (scipy is installed by .ci/setup)."""
    res, _, _ = tank
    ds = res.to_xarray()
    path = tmp_path / "tank.nc"
    ds.to_netcdf(path, engine="scipy")
    with xr.open_dataset(path) as back:
        for name in ("elevation.fx", "energy.total", "gun.a1"):
            assert np.array_equal(back[name].to_numpy(), res[name])
            assert back[name].attrs["units"] == ds[name].attrs["units"]
        assert back.attrs["fingerprint"] == ds.attrs["fingerprint"]


def test_a_csv_without_its_json_has_unknown_units(tank, tmp_path):
    res, _, csv = tank
    alone = tmp_path / "alone.csv"
    shutil.copy(csv, alone)
    bare = pymr.load_results(alone)
    df, ds = bare.to_pandas(), bare.to_xarray()
    assert np.array_equal(df["muzzle.x"].to_numpy(), res["muzzle.x"])
    assert set(df.attrs["units"]) == set(res.columns) and set(df.attrs["units"].values()) == {""}
    assert df.attrs["columns"]["muzzle.x"] == {"group": "", "owner": "", "quantity": "", "unit": ""}
    assert ds["muzzle.x"].attrs["unit"] == "" and ds.attrs["fingerprint"] == ""
    assert df.attrs["title"] == res.title             # the CSV's comment lines still give it


@pytest.mark.parametrize("method, package", [("to_pandas", "pandas"), ("to_xarray", "xarray")])
def test_missing_package_is_a_results_error(tank, monkeypatch, method, package):
    res, _, _ = tank
    monkeypatch.setitem(sys.modules, package, None)      # import fails as when not installed
    with pytest.raises(pymr.ResultsError, match=f"Results.{method}\\(\\) needs the Python package {package}"):
        getattr(res, method)()
