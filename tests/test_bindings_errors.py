"""The gfcs exception hierarchy: classes, the mapping of every core error variant, the panic barrier, and
`import gfcs` without the optional dependencies."""

from __future__ import annotations

import subprocess
import sys

import pytest

import gfcs
import gfcs.errors
from gfcs import _core

HIERARCHY = {
    "GfcsError": (Exception,),
    "UrdfError": (gfcs.GfcsError,),
    "LinkError": (gfcs.GfcsError, KeyError),
    "MeshError": (gfcs.GfcsError, OSError),
    "ShapeError": (gfcs.GfcsError, ValueError),
    "NonFiniteError": (gfcs.GfcsError, ValueError),
    "FormatError": (gfcs.GfcsError, ValueError),
    "InvalidValueError": (gfcs.GfcsError, ValueError),
    "IoError": (gfcs.GfcsError, OSError),
}

VARIANTS = {
    "Urdf": ("UrdfError", "robot.urdf"),
    "MissingLink": ("LinkError", "nolink"),
    "MissingJoint": ("LinkError", "nojoint"),
    "Mesh": ("MeshError", "a.stl"),
    "Shape": ("ShapeError", r"q: expected shape \(7,\), got \(3,\)"),
    "NonFinite": ("NonFiniteError", "q contains NaN"),
    "Format": ("FormatError", "s.yaml: field 'radius'"),
    "Value": ("InvalidValueError", "invalid dt"),
    "Io": ("IoError", "x.yaml"),
}


@pytest.mark.parametrize("name,bases", HIERARCHY.items())
def test_hierarchy(name, bases):
    cls = getattr(gfcs, name)
    assert cls is getattr(gfcs.errors, name) is getattr(_core, name)
    for base in bases:
        assert issubclass(cls, base)
    assert issubclass(cls, gfcs.GfcsError)
    assert cls.__module__ == "gfcs._core"
    assert cls.__doc__


def test_config_error_alias():
    assert gfcs.ConfigError is gfcs.InvalidValueError
    assert gfcs.errors.ConfigError is gfcs.InvalidValueError


@pytest.mark.parametrize("variant,expected", VARIANTS.items())
def test_every_core_variant_maps_to_its_exception(variant, expected):
    cls_name, pattern = expected
    with pytest.raises(getattr(gfcs, cls_name), match=pattern):
        _core._raise_core_error(variant)


def test_link_error_message_is_not_quoted():
    try:
        _core._raise_core_error("MissingLink")
    except gfcs.LinkError as e:
        assert str(e) == "no link named 'nolink' in robot 'r'"
        assert isinstance(e, KeyError)


def test_panic_becomes_gfcs_error_not_panic_exception():
    with pytest.raises(gfcs.GfcsError, match="internal error: deliberate panic") as info:
        _core._raise_internal_panic()
    assert type(info.value) is gfcs.GfcsError
    # the interpreter is still usable afterwards
    assert gfcs.Robot.panda().dof == 7


def test_import_without_optional_dependencies():
    code = (
        "import sys\n"
        "sys.modules['torch'] = None\n"
        "sys.modules['rerun'] = None\n"
        "import gfcs\n"
        "assert gfcs.Robot.panda().dof == 7\n"
        "from gfcs import *\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_lazy_submodule_and_unknown_attribute():
    with pytest.raises(AttributeError, match="no_such_thing"):
        gfcs.no_such_thing  # noqa: B018
    assert "Robot" in dir(gfcs)
