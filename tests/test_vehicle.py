"""Vehicle models: loading, parameter sets, validation and packaging."""

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import mujoco
import numpy as np
import pytest

import marinejax as mj
from marinejax.vehicle import model_dir

ROOT = Path(__file__).resolve().parents[1]


def test_both_vehicles_are_listed():
    assert {"bluerov2", "bluerov2_heavy"} <= set(mj.list_vehicles())


@pytest.mark.parametrize("name,thrusters,mass", [("bluerov2_heavy", 8, 13.5), ("bluerov2", 6, 11.2)])
def test_models_are_free_bodies_without_mujoco_fluid(name, thrusters, mass):
    v = mj.load_vehicle(name)
    m = v.mj_model
    assert v.num_actuators == thrusters
    assert m.body_mass[1] == pytest.approx(mass)
    assert m.opt.density == 0 and m.opt.viscosity == 0
    assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "chase") >= 0
    assert m.ngeom > thrusters + 3  # frame, float, tubes and one body per thruster
    assert v.source


def test_heavy_defaults_to_von_benzon_and_offers_wu():
    v = mj.load_vehicle("bluerov2_heavy")
    assert v.param_set == "vonbenzon2022" and "wu2018" in v.param_sets
    np.testing.assert_allclose(v.sys.hydro.added_mass, [6.36, 7.12, 18.68, 0.189, 0.135, 0.222], rtol=1e-6)
    wu = mj.load_vehicle("bluerov2_heavy", param_set="wu2018")
    assert float(wu.sys.model.body_mass[1]) == pytest.approx(11.5)
    np.testing.assert_allclose(wu.sys.model.body_inertia[1], [0.16] * 3, rtol=1e-6)
    buoyancy = float(wu.sys.hydro.fluid_density * 9.81 * wu.sys.hydro.volume)
    assert buoyancy == pytest.approx(114.8, abs=0.05)  # Wu 2018: B = 114.8 N


def test_unknown_names_list_the_choices():
    with pytest.raises(ValueError, match=r"unknown vehicle 'bluerov3'.*'bluerov2'.*'bluerov2_heavy'"):
        mj.load_vehicle("bluerov3")
    with pytest.raises(ValueError, match=r"unknown parameter set 'wu'.*\['vonbenzon2022', 'wu2018'\]"):
        mj.load_vehicle("bluerov2_heavy", param_set="wu")


def _edited_model(tmp_path, pattern, replacement):
    text = (model_dir() / "bluerov2_heavy.xml").read_text()
    edited, n = re.subn(pattern, replacement, text)
    assert n == 1
    path = tmp_path / "edited_rov.xml"
    path.write_text(edited)
    return path


def test_non_finite_parameter_in_a_model_file_is_rejected(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its NaN warning to MUJOCO_LOG.TXT in the working directory
    path = _edited_model(tmp_path, r'(vonbenzon2022:quadratic_damping" data=")141', r"\1nan")
    with pytest.raises(ValueError, match=r"edited_rov.*'quadratic_damping' has non-finite"):
        mj.load_vehicle(path)


def test_negative_volume_in_a_model_file_is_rejected(tmp_path):
    path = _edited_model(tmp_path, r'(vonbenzon2022:volume" data=")0.0134', r"\1-0.0134")
    with pytest.raises(ValueError, match=r"'volume' must be > 0"):
        mj.load_vehicle(path)


def test_body_origin_must_be_the_centre_of_gravity(tmp_path):
    path = _edited_model(tmp_path, r'<inertial pos="0 0 0"', '<inertial pos="0 0 -0.02"')
    with pytest.raises(ValueError, match="centre of gravity"):
        mj.load_vehicle(path)


def test_wheel_ships_models_and_data(tmp_path):
    """A non-editable install must find the MJCF files and the T200 table inside the package."""
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path), str(ROOT)],
        check=True,
    )
    (wheel,) = tmp_path.glob("marinejax-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert "marinejax/models/mjcf/bluerov2_heavy.xml" in names
    assert "marinejax/models/mjcf/bluerov2.xml" in names
    assert "marinejax/data/t200_bollard_10-20V.csv" in names
    assert "marinejax/policies/BlueROV2Heavy-StationKeeping/config.json" in names
    assert any(n.startswith("marinejax/policies/BlueROV2Heavy-StationKeeping/checkpoints/") for n in names)
