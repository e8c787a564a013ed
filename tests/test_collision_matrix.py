"""gfcs.collision_matrix: Setup Assistant's reasons on a generated robot whose pairs are built to have each."""

import json
import xml.etree.ElementTree as ET

import pytest

from gfcs import cli
from gfcs.collision_matrix import adjacent_body_pairs, adjacent_pairs, collision_matrix, srdf_with_pairs
from gfcs.errors import FormatError, InvalidValueError, IoError


def _box(size, xyz):
    s = " ".join(map(str, size))
    o = " ".join(map(str, xyz))
    return f'<collision><origin xyz="{o}"/><geometry><box size="{s}"/></geometry></collision>'


def _joint(name, kind, parent, child, xyz="0 0 0", limits="-3.14 3.14", axis="0 0 1"):
    lo, up = limits.split()
    limit = f'<limit lower="{lo}" upper="{up}" velocity="1" effort="1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit}</joint>')


@pytest.fixture
def urdf(tmp_path):
    """base (fixed plate), arm1 on a revolute joint, arm2 on arm1, a slider on base. Built so that:
    plate-arm1 touch at q = 0 (Default); the slider touches the plate once it moves 1 cm of its 102 cm
    (Always, 97 %); arm2 stays 0.6 m from base (Never)."""
    text = (
        '<robot name="cm">'
        f'<link name="base">{_box((0.1, 0.1, 0.1), (0, 0, 0))}</link>'
        f'<link name="plate">{_box((1.0, 0.1, 0.1), (0.56, 0.3, 0))}</link>'
        f'<link name="arm1">{_box((0.1, 0.6, 0.1), (0.5, 0, 0))}</link>'
        f'<link name="arm2">{_box((0.1, 0.1, 0.1), (0.3, 0, 0))}</link>'
        f'<link name="slider">{_box((0.1, 0.1, 0.1), (0, 0.3, 0))}</link>'
        '<link name="flange"/>'
        + _joint("fix", "fixed", "base", "plate")
        + _joint("j1", "revolute", "base", "flange")
        + _joint("j1b", "fixed", "flange", "arm1")
        + _joint("j2", "revolute", "arm1", "arm2", xyz="1 0 0")
        + _joint("slide", "prismatic", "base", "slider", limits="-0.02 1.0", axis="1 0 0")
        + "</robot>")
    path = tmp_path / "cm.urdf"
    path.write_text(text)
    return path


def test_each_reason_where_the_robot_was_built_to_have_it(urdf):
    assert adjacent_pairs(urdf) == [("base", "arm1"), ("arm1", "arm2"), ("base", "plate"), ("base", "slider")]
    # plate is base's body: arm1 and the slider are on bodies adjacent to it
    assert ("arm1", "plate") in adjacent_body_pairs(urdf) and ("plate", "slider") in adjacent_body_pairs(urdf)
    pairs = {(p.link1, p.link2): p.reason for p in collision_matrix(urdf, samples=2000, seed=1)}
    for a, b in adjacent_pairs(urdf):
        assert pairs[tuple(sorted((a, b)))] == "Adjacent"
    assert pairs[("arm1", "plate")] == "Default"
    assert pairs[("plate", "slider")] == "Always"
    assert pairs[("arm2", "base")] == "Never"
    # arm1 sweeps across the slider's track: they touch at some configurations, and stay checked
    assert ("arm1", "slider") not in pairs
    again = {(p.link1, p.link2): p.reason for p in collision_matrix(urdf, samples=2000, seed=1)}
    assert again == pairs


def test_the_srdf_keeps_its_groups_and_adds_each_pair_once(urdf, tmp_path):
    base = tmp_path / "base.srdf"
    base.write_text('<robot name="cm"><group name="arm"><joint name="j1"/><joint name="j2"/></group>'
                    '<disable_collisions link1="arm2" link2="base" reason="Never"/></robot>')
    pairs = collision_matrix(urdf, samples=500)
    root = ET.fromstring(srdf_with_pairs(pairs, "cm", base))
    assert root.find("group").get("name") == "arm"
    listed = [frozenset((e.get("link1"), e.get("link2"))) for e in root.iter("disable_collisions")]
    assert len(listed) == len(set(listed)) == len(pairs)


def test_the_command_writes_the_srdf_and_json(urdf, tmp_path, capsys):
    out = tmp_path / "cm.srdf"
    assert cli.main(["collision-matrix", str(urdf), "-o", str(out), "--samples", "500", "--json",
                     "--no-progress"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert sum(report["counts"].values()) == len(report["pairs"]) > 0
    assert len(list(ET.parse(out).getroot().iter("disable_collisions"))) == len(report["pairs"])


def test_bad_arguments_name_themselves(urdf, tmp_path, capsys):
    for kwargs, name in ((dict(samples=0), "samples"), (dict(always=0.0), "always"), (dict(contact=-1.0), "contact")):
        with pytest.raises(InvalidValueError, match=name):
            collision_matrix(urdf, **kwargs)
    with pytest.raises(IoError, match="missing.urdf: cannot read URDF"):
        collision_matrix(tmp_path / "missing.urdf")
    still = tmp_path / "still.urdf"
    still.write_text('<robot name="s"><link name="a"/></robot>')
    with pytest.raises(InvalidValueError, match="still.urdf: no movable joint"):
        collision_matrix(still)
    # the command refuses an unwritable -o before it samples
    assert cli.main(["collision-matrix", str(urdf), "-o", str(tmp_path / "no" / "such.srdf")]) == 2
    err = capsys.readouterr().err
    assert "-o" in err and "does not exist" in err
    bad = tmp_path / "bad.srdf"
    bad.write_text("<robot")
    with pytest.raises(FormatError, match="bad.srdf"):
        srdf_with_pairs([], "cm", bad)
