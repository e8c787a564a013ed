"""gfcs.cache and the fitted-sphere cache: an entry round-trips exactly, a changed mesh or parameter misses, a
corrupt or unwritable cache is recomputed or skipped, GFCS_CACHE_DIR=off turns it off, and the CLI says where
the spheres came from."""

import json

import numpy as np
import pytest

import gfcs
from gfcs import cache, cli, coverage, sphere_fit

CUBE_OBJ = "\n".join(
    [f"v {x} {y} {z}" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    + ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]) + "\n"


def _mesh_robot(tmp_path, scale=0.05):
    """A two-link arm whose moving link's collision geometry is an OBJ cube of half edge ``scale`` m."""
    mesh = tmp_path / "cube.obj"
    mesh.write_text(CUBE_OBJ)
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(f"""<robot name="arm"><link name="base"/>
      <link name="link"><collision><origin xyz="0.2 0 0"/><geometry><mesh filename="{mesh}"
        scale="{scale} {scale} {scale}"/></geometry></collision></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="link"/><axis xyz="0 0 1"/>
        <limit lower="-2" upper="2" velocity="1" effort="1"/></joint></robot>""")
    return urdf, mesh


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("GFCS_CACHE_DIR", str(root))
    return root


def test_entries_round_trip_and_bad_entries_read_as_missing(cache_dir):
    value = [["link", [0.1, -2.5e-7, 1.0 / 3.0], 0.123457]]
    path = cache.store("spheres", "k", value)
    assert path == cache_dir / "spheres" / "k.json" and cache.load("spheres", "k") == value
    assert cache.load("spheres", "other") is None
    path.write_text("{not json")
    assert cache.load("spheres", "k") is None
    assert cache.digest("a", 1, (2.0,)) == cache.digest("a", 1, (2.0,)) != cache.digest("a", 1, (2.5,))
    assert cache.file_digest(cache_dir / "nothing") == "missing"


def test_off_and_unwritable_caches_store_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("GFCS_CACHE_DIR", "off")
    assert cache.directory() is None and cache.store("spheres", "k", [1]) is None and cache.load("spheres", "k") is None
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("GFCS_CACHE_DIR", str(blocker))  # a file where the directory should be
    assert cache.store("spheres", "k", [1]) is None
    monkeypatch.delenv("GFCS_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.directory() == tmp_path / "xdg" / "gfcs"


def test_fitted_spheres_are_read_back_exactly_and_refit_when_the_mesh_changes(tmp_path, cache_dir, monkeypatch):
    urdf, mesh = _mesh_robot(tmp_path)
    robot = gfcs.Robot.from_urdf(str(urdf))
    first = sphere_fit.fitted_spheres(robot)
    assert first and len(list((cache_dir / "spheres").glob("*.json"))) == 1

    def no_fit(*args, **kwargs):
        raise AssertionError("fitted again instead of reading the cache")

    real_fit = sphere_fit.fit_link_spheres
    monkeypatch.setattr(sphere_fit, "fit_link_spheres", no_fit)
    cached = []
    assert sphere_fit.fitted_spheres(robot, cached=cached) == first
    assert len(cached) == 1 and json.loads(open(cached[0]).read()) == [list(s) for s in first]
    # other parameters or other mesh bytes are another entry
    monkeypatch.setattr(sphere_fit, "fit_link_spheres", real_fit)
    wider = sphere_fit.fitted_spheres(robot, margin=0.01)
    assert [r for _, _, r in wider] != [r for _, _, r in first]
    mesh.write_text(CUBE_OBJ.replace("v 1 1 1", "v 2 2 2"))
    coverage._link_points.cache_clear()  # the points of a mesh path are kept per process
    moved = sphere_fit.fitted_spheres(gfcs.Robot.from_urdf(str(urdf)))
    assert moved != first and len(list((cache_dir / "spheres").glob("*.json"))) == 3


def test_a_corrupt_entry_is_refit_and_off_always_fits(tmp_path, cache_dir, monkeypatch):
    urdf, _ = _mesh_robot(tmp_path)
    robot = gfcs.Robot.from_urdf(str(urdf))
    first = sphere_fit.fitted_spheres(robot)
    (entry,) = (cache_dir / "spheres").glob("*.json")
    entry.write_text("[1, 2")
    cached = []
    assert sphere_fit.fitted_spheres(robot, cached=cached) == first and cached == []
    monkeypatch.setenv("GFCS_CACHE_DIR", "off")
    assert sphere_fit.fitted_spheres(robot, cached=cached) == first and cached == []


def test_the_cli_says_the_spheres_came_from_the_cache(tmp_path, cache_dir, capsys):
    urdf, _ = _mesh_robot(tmp_path)
    first = cli._robot(cli.build_parser().parse_args(["solve", "--robot", str(urdf)]))
    assert "fitted to their geometry in" in capsys.readouterr().err
    again = cli._robot(cli.build_parser().parse_args(["solve", "--robot", str(urdf)]))
    err = capsys.readouterr().err
    assert f"read from the cache {cache_dir}" in err and "GFCS_CACHE_DIR=off" in err
    np.testing.assert_array_equal(again.sphere_radii, first.sphere_radii)
    np.testing.assert_array_equal(again.sphere_centers_local, first.sphere_centers_local)
