"""package:// mesh paths resolved as ROS resolves them: by the name in a package's package.xml, below the mesh
directory or a ROS_PACKAGE_PATH root."""

import pytest

import gfcs

CUBE_OBJ = "\n".join(
    [f"v {x} {y} {z}" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    + ["f 1 2 4 3", "f 5 7 8 6", "f 1 5 6 2", "f 3 4 8 7", "f 1 3 7 5", "f 2 6 8 4"]) + "\n"

ARM = """<robot name="arm"><link name="base"/>
  <link name="link"><collision><origin xyz="0.2 0 0"/><geometry><mesh filename="{mesh}" scale="0.05 0.05 0.05"/>
  </geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="link"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="1" effort="1"/></joint></robot>"""


def test_package_meshes_are_found_by_the_name_in_their_package_xml(tmp_path, monkeypatch):
    """A package:// mesh whose package lives in a folder of another name (a ROS workspace: the package
    `moveit_resources_arm` in `src/arm/`) resolves below the mesh directory or a ROS_PACKAGE_PATH root, as ROS
    resolves it; the validator's meshes load from it."""
    pkg = tmp_path / "ws" / "src" / "arm"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package format='3'><name>moveit_resources_arm</name></package>")
    (pkg / "meshes" / "cube.obj").write_text(CUBE_OBJ)
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(ARM.format(mesh="package://moveit_resources_arm/meshes/cube.obj"))
    (mesh,) = gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(tmp_path / "ws")).collision_geometry()
    assert mesh["exists"] and mesh["path"] == str(pkg / "meshes" / "cube.obj")
    assert gfcs.MeshChecker(gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(tmp_path / "ws"))).num_shapes == 1
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (missing,) = gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(elsewhere)).collision_geometry()
    assert not missing["exists"]
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ws" / "src"))
    (found,) = gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(elsewhere)).collision_geometry()
    assert found["exists"] and found["path"] == str(pkg / "meshes" / "cube.obj")
    with pytest.raises(gfcs.MeshError, match="package.xml naming its package"):
        monkeypatch.delenv("ROS_PACKAGE_PATH")
        gfcs.MeshChecker(gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(elsewhere)))
