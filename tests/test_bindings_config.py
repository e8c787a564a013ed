"""gfcs.FabricConfig bindings: defaults, dict / file round trips in every format, replace, and errors that
name the file and the dotted field."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

import gfcs


def test_defaults_and_dict_round_trip():
    cfg = gfcs.FabricConfig()
    assert cfg == gfcs.FabricConfig.defaults()
    d = cfg.to_dict()
    assert d["mode"] == "bent"
    assert {"joint_attraction", "ee_position", "ee_orientation", "joint_limits", "self_collision", "obstacles",
            "speed"} <= set(d)
    assert gfcs.FabricConfig(d) == cfg
    assert gfcs.FabricConfig.from_dict(d) == cfg
    assert json.loads(cfg.to_json()) == d
    assert "FabricConfig(" in repr(cfg)


def test_partial_dict_merges_over_defaults():
    cfg = gfcs.FabricConfig({"speed": {"desired_speed": 0.7}, "mode": "unbent"})
    d = cfg.to_dict()
    assert d["speed"]["desired_speed"] == 0.7 and d["mode"] == "unbent"
    default = gfcs.FabricConfig().to_dict()
    assert d["obstacles"] == default["obstacles"]
    assert d["speed"]["goal_damping"] == default["speed"]["goal_damping"]
    # numpy scalars are accepted
    cfg2 = gfcs.FabricConfig({"speed": {"desired_speed": np.float64(0.7), "enabled": np.bool_(True)}, "mode": "unbent"})
    assert cfg2 == cfg


def test_replace():
    cfg = gfcs.FabricConfig()
    a = cfg.replace({"obstacles": {"margin": 0.02}})
    b = cfg.replace(obstacles={"margin": 0.02})
    assert a == b != cfg
    assert a.to_dict()["obstacles"]["margin"] == 0.02
    assert a.to_dict()["obstacles"]["metric_gain"] == cfg.to_dict()["obstacles"]["metric_gain"]
    assert cfg.to_dict()["obstacles"]["margin"] == gfcs.FabricConfig().to_dict()["obstacles"]["margin"]


def test_files_in_every_format(tmp_path):
    d = gfcs.FabricConfig({"joint_attraction": {"mass": 2.5}}).to_dict()
    (tmp_path / "c.json").write_text(json.dumps(d))
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(d))
    (tmp_path / "c.yml").write_text(yaml.safe_dump({"joint_attraction": {"mass": 2.5}}))
    (tmp_path / "c.toml").write_text("[joint_attraction]\nmass = 2.5\n")
    expected = gfcs.FabricConfig(d)
    for name in ("c.json", "c.yaml", "c.yml", "c.toml"):
        assert gfcs.FabricConfig.from_file(tmp_path / name) == expected, name
    assert gfcs.FabricConfig.from_str("[joint_attraction]\nmass = 2.5\n") == expected
    assert gfcs.FabricConfig.from_str(json.dumps(d), format="json") == expected
    assert gfcs.FabricConfig.from_str("joint_attraction: {mass: 2.5}", format="yaml") == expected


def test_errors_name_file_and_field(tmp_path):
    with pytest.raises(gfcs.FormatError, match=r"<dict>: field 'speed\.desired_sped'"):
        gfcs.FabricConfig({"speed": {"desired_sped": 1.0}})
    with pytest.raises(gfcs.FormatError, match=r"obstacles\.margin"):
        gfcs.FabricConfig({"obstacles": {"margin": "wide"}})
    with pytest.raises(gfcs.FormatError, match=r"joint_attraction\.mass"):
        gfcs.FabricConfig({"joint_attraction": {"mass": -1.0}})
    with pytest.raises(gfcs.NonFiniteError, match=r"speed\.desired_speed"):
        gfcs.FabricConfig({"speed": {"desired_speed": float("nan")}})
    bad = tmp_path / "bad.toml"
    bad.write_text("[speed]\nunknown_gain = 1.0\n")
    with pytest.raises(gfcs.FormatError, match=r"bad\.toml: field 'speed\.unknown_gain'"):
        gfcs.FabricConfig.from_file(bad)
    with pytest.raises(gfcs.FormatError, match="extension"):
        (tmp_path / "c.ini").write_text("")
        gfcs.FabricConfig.from_file(tmp_path / "c.ini")
    with pytest.raises(gfcs.IoError, match="absent.toml"):
        gfcs.FabricConfig.from_file(tmp_path / "absent.toml")
    with pytest.raises(gfcs.InvalidValueError, match="format"):
        gfcs.FabricConfig.from_str("", format="ini")
    with pytest.raises(gfcs.FormatError, match="speed"):
        gfcs.FabricConfig().replace(speed={"nope": 1})
