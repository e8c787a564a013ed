#!/usr/bin/env bash
# Fuzz the file readers (cargo-fuzz, libFuzzer): URDF, SRDF, MoveIt scene/request YAML, OBJ/STL meshes.
#
#   scripts/fuzz.sh [SECONDS] [TARGET ...]
#
# Runs each target (default: urdf srdf moveit_yaml mesh) for SECONDS (default 600), one after another at
# the lowest CPU priority, on one core. Corpora grow in fuzz/corpus/<target> (seeded from the shipped
# Panda's files, and from the shared MotionBenchMaker data when $GFCS_SHARED or ../shared exists);
# crashing inputs land in fuzz/artifacts/<target>; logs in fuzz/logs/<target>.log. Prints one line per
# target: inputs tried, seconds, crashes. Exits non-zero when any target crashed.
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
seconds="${1:-600}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(urdf srdf moveit_yaml mesh)
shared="${GFCS_SHARED:-$(cd .. && pwd)/../shared}"
assets=../crates/fabric-core/assets

seed() {  # seed TARGET FILE...: copy the readable files into the target's corpus
    local dir="corpus/$1"; shift
    mkdir -p "$dir"
    for f in "$@"; do [ -f "$f" ] && cp -n "$f" "$dir/" || true; done
}
seed urdf "$assets/panda.urdf" "$shared"/robots/*/*.urdf
seed srdf "$assets/panda.srdf" "$shared"/robots/*/*.srdf
seed moveit_yaml "$shared"/mbm/box/scene0001.yaml "$shared"/mbm/box/request0001.yaml \
    "$shared"/mbm_fetch/cage/scene0001.yaml "$shared"/mbm_ur5/table_pick/request0001.yaml
seed mesh ../python/gfcs/data/panda_hulls/panda_hand.obj ../python/gfcs/data/panda_hulls/panda_link1.obj

mkdir -p logs
status=0
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    set +e
    nice -n 19 cargo +nightly fuzz run -O "$t" "corpus/$t" -- \
        -max_total_time="$seconds" -max_len=262144 -timeout=10 -rss_limit_mb=2048 \
        -artifact_prefix="artifacts/$t/" > "logs/$t.log" 2>&1
    rc=$?
    set -e
    runs=$(grep -o 'Done [0-9]* runs in [0-9]* second' "logs/$t.log" | tail -1)
    crashes=$(find "artifacts/$t" -type f | wc -l)
    echo "$t: ${runs:-no summary (see fuzz/logs/$t.log)}; exit $rc; crash artifacts: $crashes"
    [ "$rc" -eq 0 ] && [ "$crashes" -eq 0 ] || status=1
done
exit $status
