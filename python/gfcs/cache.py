"""A disk cache for results that depend only on files and parameters: the collision spheres fitted to a robot
described by meshes only (:func:`gfcs.sphere_fit.fitted_spheres`) are computed once per machine, not on every
``gfcs solve`` (seconds for a two-arm robot, against a solve of a fraction of a second).

Location: the directory in the environment variable ``GFCS_CACHE_DIR``, else ``$XDG_CACHE_HOME/gfcs``, else
``~/.cache/gfcs``; ``GFCS_CACHE_DIR=off`` turns the cache off. An entry is a JSON file named by the SHA-256 of
everything its result depends on (:func:`digest` of the caller's parts: file contents, parameters, and the
source of the code that computes it), so a changed mesh, parameter or gfcs release misses. A missing, unreadable
or malformed entry is recomputed, and a cache that cannot be written is left alone: the cache only ever saves
time.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Optional

__all__ = ["directory", "digest", "file_digest", "entry", "load", "store", "OFF"]

#: The value of ``GFCS_CACHE_DIR`` that turns the cache off.
OFF = "off"


def directory() -> Optional[Path]:
    """The cache directory (it may not exist yet), or None when ``GFCS_CACHE_DIR=off``."""
    chosen = os.environ.get("GFCS_CACHE_DIR")
    if chosen is not None:
        return None if chosen.strip().lower() == OFF else Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME")
    return (Path(base) if base else Path.home() / ".cache") / "gfcs"


def file_digest(path: Any) -> str:
    """SHA-256 (hex) of a file's bytes; "missing" when it cannot be read (a missing mesh is part of the key)."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return "missing"
    return h.hexdigest()


def digest(*parts: Any) -> str:
    """SHA-256 (hex) of ``parts`` by their ``repr`` (tuples, strings and numbers: a stable text)."""
    return hashlib.sha256(repr(parts).encode()).hexdigest()


def entry(kind: str, key: str) -> Optional[Path]:
    """The file of the entry ``kind``/``key`` (it may not exist), or None when the cache is off."""
    root = directory()
    return None if root is None else root / kind / f"{key}.json"


def load(kind: str, key: str) -> Optional[Any]:
    """The value stored under ``kind``/``key`` (:func:`store`), or None when there is none (or the cache is off,
    or the entry cannot be read as JSON)."""
    path = entry(kind, key)
    if path is None:
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def store(kind: str, key: str, value: Any) -> Optional[Path]:
    """Write ``value`` (JSON-serialisable) under ``kind``/``key`` atomically (a reader never sees half an
    entry); the entry's path, or None when the cache is off or cannot be written."""
    path = entry(kind, key)
    if path is None:
        return None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            json.dump(value, f)
        os.replace(tmp, path)
    except OSError:
        return None
    return path
