#!/usr/bin/env bash
# A sweep on Slurm (docs/scenarios.md, "Sweeps"): on a one-node cluster of scripts/slurm-cluster
# in the test's own folder, `autodrive-scenario sweep config/scenarios/sweep_crossing.yaml
# --slurm` submits its 4 runs as an array job, follows it and writes a summary.json equal to the
# one the same sweep writes run here; `--slurm --resume` on the finished sweep submits nothing
# and writes the same summary again; after `down` no process of the cluster or of a run is left.
#
# Skips (exit 77) where this host cannot run a cluster (not root, or Slurm's packages missing).
# Run by CTest with AUTODRIVE_SOURCE_DIR and AUTODRIVE_BINARY_DIR set.
set -euo pipefail

source_dir="${AUTODRIVE_SOURCE_DIR:?run this test through ctest}"
bin="${AUTODRIVE_BINARY_DIR:?run this test through ctest}/bin"
cluster_script="$source_dir/scripts/slurm-cluster"
sweep="$source_dir/config/scenarios/sweep_crossing.yaml"

reason="$("$cluster_script" check 2>&1)" && can=0 || can=$?
if ((can == 2)); then
  echo "SKIP: $reason"
  exit 77
elif ((can != 0)); then
  echo "FAIL scripts/slurm-cluster check exited $can: $reason"
  exit 1
fi

tmp="$(realpath "$(mktemp -d "${TMPDIR:-/tmp}/scenario_slurm_test.XXXXXX")")"
# Every process of the test's runs carries this in its environment.
export AUTODRIVE_TEST_TAG="$tmp"
cleanup() {
  "$cluster_script" down "$tmp/cluster" >/dev/null 2>&1 || true
  rm -rf "$tmp"
}
trap cleanup EXIT

failures=0
check() {
  local message="$1"
  shift
  if "$@"; then echo "ok   $message"; else echo "FAIL $message"; failures=$((failures + 1)); fi
}
same_json() { /usr/bin/python3 -c 'import json,sys; sys.exit(0 if json.load(open(sys.argv[1])) == json.load(open(sys.argv[2])) else 1)' "$1" "$2"; }

"$cluster_script" up "$tmp/cluster" >"$tmp/up.out"
export SLURM_CONF="$tmp/cluster/slurm.conf"

"$bin/autodrive-scenario" sweep "$sweep" --out "$tmp/local" --quiet
"$bin/autodrive-scenario" sweep "$sweep" --out "$tmp/slurm" --slurm --quiet
check "the Slurm array job ran every run" test "$(ls "$tmp/slurm/runs"/*/report.json | wc -l)" -eq 4
check "one array job, its script and a log per task" test -s "$tmp/slurm/slurm/job_id" -a \
  "$(ls "$tmp/slurm/slurm"/*_*.out | wc -l)" -eq 4
check "summary.json on Slurm equals the local one" same_json "$tmp/local/summary.json" "$tmp/slurm/summary.json"
job="$(cat "$tmp/slurm/slurm/job_id")"
"$bin/autodrive-scenario" sweep "$sweep" --out "$tmp/slurm" --slurm --resume --quiet
check "--resume of a finished sweep submits nothing" test "$(cat "$tmp/slurm/slurm/job_id")" = "$job"
check "and summarises the same" same_json "$tmp/local/summary.json" "$tmp/slurm/summary.json"

"$cluster_script" down "$tmp/cluster" >/dev/null
left=""
for e in /proc/[0-9]*/environ; do
  pid="${e#/proc/}"
  pid="${pid%/environ}"
  [[ "$pid" == "$$" ]] && continue
  # The redirection's own error (a process gone meanwhile, one not ours) is the group's.
  if { tr '\0' '\n' <"$e"; } 2>/dev/null | grep -qx "AUTODRIVE_TEST_TAG=$tmp"; then
    state="$(awk '{ sub(/.*\) /, ""); print $1 }' "/proc/$pid/stat" 2>/dev/null || echo gone)"
    [[ "$state" != Z && "$state" != gone ]] && left+=" $pid"
  fi
done
check "no process of the runs left (${left:-none})" test -z "$left"

if ((failures)); then
  echo "$failures checks failed"
  exit 1
fi
echo "all checks passed"
