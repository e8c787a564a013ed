#!/usr/bin/env bash
# Install gfcs with every optional dependency and run all tests: the Rust core, then the Python package.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet ".[test,ray,baselines]"
cargo test --release
python3 -m pytest -q
