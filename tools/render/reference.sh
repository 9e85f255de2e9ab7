#!/usr/bin/env bash
# Renders (or checks) the reference renders of corpus/renders/: the independently rendered
# campaigns the tests regenerate without a renderer.
#
#   bash tools/render/reference.sh [REGOLITH_BINARY]
#   SET=train bash tools/render/reference.sh    # the training seeds into corpus/renders-train
#
# SET=test (default): the held-out test seeds 301-303 into corpus/renders (what the tests
# regenerate); SET=train: the calibration seeds 311-313 into corpus/renders-train (what
# tools/calibrate/ and the gap_matrix example calibrate on; no test reads them).
#
# For each seed it generates the mini campaigns with nothing hidden, with each
# catalogue effect and with the three pairs, all with --renderer mitsuba --renders corpus/renders.
# Renders already in the cache are reused (image effects act after the render, so only the plain
# scene, a moved lamp (shadows) and a moved camera (pose-bias) are rendered); missing ones are
# rendered with Mitsuba, which the script installs (tools/render/install.sh) if it is absent; if
# it cannot, it says so and stops at the first missing render with the generator's list of the
# missing shots. The campaigns go to a temporary folder.
set -euo pipefail

here=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:-$here/target/release/regolith}
case ${SET:-test} in
    test) renders=$here/corpus/renders; seeds="301 302 303" ;;
    train) renders=$here/corpus/renders-train; seeds="311 312 313" ;;
    *) echo "SET must be test or train" >&2; exit 2 ;;
esac
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

# The test seeds, cases and sample count are also those of tests/tests/corpus/physical.rs.
spp=${SPP:-128}
cases="none vignetting blur noise gamma exposure shadows distortion pose-bias texture-lowpass
vignetting,exposure blur,distortion shadows,gamma"

if ! python3 -c "import mitsuba" 2>/dev/null; then
    echo "mitsuba is not installed: running tools/render/install.sh" >&2
    if ! bash "$here/tools/render/install.sh"; then
        echo "cannot install Mitsuba here: only the renders already in $renders can be used;" >&2
        echo "a missing one stops the script with the generator's list of missing shots" >&2
    fi
fi
for seed in $seeds; do
    for case in $cases; do
        hidden=()
        [ "$case" = none ] || hidden=(--hidden-effect "$case")
        echo "== seed $seed: $case" >&2
        "$bin" corpus generate --preset mini --seed "$seed" "${hidden[@]}" \
            --renderer mitsuba --renders "$renders" --spp "$spp" \
            --out "$out/$seed-${case//,/+}" -q
    done
done
du -sh "$renders"
ls "$renders"/*.png | wc -l
