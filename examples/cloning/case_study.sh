#!/usr/bin/env bash
# The paper's behavioural-cloning case study, end to end (README.md beside this file):
#   1. record 5 laps of the Driving School's figure of eight, one per seed (101-105: each its own
#      light and start), with the lane driver as the demonstrator;
#   2. train the 6-layer CNN on them (4 epochs, Adam, 1e-3) and write the model;
#   3. let the model drive 5 laps on 10 other seeds (1-10) in the scenario runner;
#   4. print the runner's figures per seed (collisions, lane departures, laps and lap times).
# Usage: examples/cloning/case_study.sh OUT_DIR   (the build in build/, or $AUTODRIVE_BUILD_DIR)
set -euo pipefail
out="${1:?usage: examples/cloning/case_study.sh OUT_DIR}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${AUTODRIVE_BUILD_DIR:-$repo/build}/bin"
route="r2c0:N>E:0,r2c1:W>E:0,r2c3:W>E:0,r2c4:W>S:0,r3c4:N>S:0,r4c4:N>W:0,r4c3:E>W:0,r4c2:E>N:0"
route="$route,r3c2:S>N:0,r1c2:S>N:0,r0c2:S>W:0,r0c1:E>W:0,r0c0:E>S:0,r1c0:N>S:0"
mkdir -p "$out"
laps=()
for seed in 101 102 103 104 105; do
  "$bin/autodrive-sim" record --city "$repo/config/cities/driving_school.yaml" --route "$route" \
    --seed "$seed" --out "$out/laps/lap_$seed" --quiet
  laps+=("$out/laps/lap_$seed")
done
echo "recorded: $(cat "$out"/laps/*/labels.csv | grep -vc '^frame') frames in 5 laps"
(IFS=,; "$bin/autodrive-example-cloning-train" --data "${laps[*]}" --out "$out/model.pt" --quiet) |
  tee "$out/training.txt"
AUTODRIVE_CLONING_MODEL="$out/model.pt" "$bin/autodrive-scenario" sweep \
  "$repo/config/scenarios/sweep_cloning_driving_school.yaml" --out "$out/sweep" --quiet
python3 "$repo/examples/cloning/cloning_figures.py" "$out/sweep"
