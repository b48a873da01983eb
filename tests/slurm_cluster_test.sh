#!/usr/bin/env bash
# The one-node Slurm cluster of scripts/slurm-cluster, on which the sweeps' Slurm tests run:
#   1. `up` in the test's own temporary folder prints the line to export; a second `up` is a
#      no-op that says so; `status` says all three daemons run;
#   2. an array job of 4 tasks (sbatch --array=0-3) runs through it: each task writes its
#      SLURM_ARRAY_JOB_ID and SLURM_ARRAY_TASK_ID into a file of its own; all four files hold
#      the submitted job's id and their index, and Slurm reports every task COMPLETED with exit
#      code 0 (found by polling squeue and the files with a deadline: there is no accounting);
#   3. `down` stops everything: none of the daemons recorded at `up` is left, nor any process
#      that carries the cluster's marker or its SLURM_CONF, nor any naming the test's folder.
# Whatever happens, the EXIT trap brings the cluster down and removes the folder. After a killed
# run, `scripts/slurm-cluster down DIR` (the folder is printed first) leaves nothing either.
# Prints how long `up` and the array took (figures, not asserted).
#
# Skips (exit 77, CTest's SKIP_RETURN_CODE) when this host cannot run a cluster: not root, or
# Debian's slurmctld, slurmd, slurm-client or munge missing. Run by CTest (tests/CMakeLists.txt)
# with AUTODRIVE_SOURCE_DIR set. Exit 0 when every check holds.
set -euo pipefail

source_dir="${AUTODRIVE_SOURCE_DIR:?AUTODRIVE_SOURCE_DIR is not set: run this test through ctest}"
cluster_script="$source_dir/scripts/slurm-cluster"
deadline_s=120
tasks=4

reason="$("$cluster_script" check 2>&1)" && can=0 || can=$?
if ((can == 2)); then
  echo "SKIP: $reason"
  exit 77
elif ((can != 0)); then
  echo "FAIL scripts/slurm-cluster check exited $can: $reason"
  exit 1
fi

tmp="$(realpath "$(mktemp -d "${TMPDIR:-/tmp}/slurm_cluster_test.XXXXXX")")"
cluster="$tmp/cluster"
work="$tmp/work"
mkdir -p "$work/results" "$work/out"
echo "cluster folder: $cluster (after a killed run: scripts/slurm-cluster down $cluster)"

# check MESSAGE COMMAND...: runs COMMAND (a test) and counts a failure when it fails.
failures=0
check() {
  local message="$1"
  shift
  if "$@"; then
    echo "ok   $message"
  else
    echo "FAIL $message"
    failures=$((failures + 1))
  fi
}

now() { echo "${EPOCHREALTIME/[.,]/}"; } # microseconds
seconds_since() { printf '%d.%02d' $((($(now) - $1) / 1000000)) $(((($(now) - $1) / 10000) % 100)); }

# The daemons' pids as `up` left them, with their start times (field 22 of /proc/PID/stat), so
# that a pid used again by another process is not taken for a daemon left behind.
declare -A daemon_start=()
start_time() { awk '{ sub(/.*\) /, ""); print $20 }' "/proc/$1/stat" 2>/dev/null; }
state_of() { awk '{ sub(/.*\) /, ""); print $1 }' "/proc/$1/stat" 2>/dev/null; }

# Prints "PID COMMAND LINE" for every live process of the cluster (a zombie waiting for PID 1
# to reap it is not one): a daemon recorded at `up`, a process with the cluster's marker or
# SLURM_CONF in its environment, or one whose command line names the test's folder.
leftovers() {
  local pid file state
  local -A found=()
  for pid in "${!daemon_start[@]}"; do
    if [ "$(start_time "$pid")" = "${daemon_start[$pid]}" ]; then
      found[$pid]=1
    fi
  done
  while read -r file; do
    pid="${file#/proc/}"
    found[${pid%%/*}]=1
  done < <(grep -lszxF -e "AUTODRIVE_SLURM_CLUSTER=$cluster" -e "SLURM_CONF=$cluster/slurm.conf" \
    /proc/[0-9]*/environ || true; grep -lsaF -e "$tmp/" /proc/[0-9]*/cmdline || true)
  for pid in "${!found[@]}"; do
    if [ "$pid" = $$ ] || [ "$pid" = "$BASHPID" ]; then continue; fi
    state="$(state_of "$pid")"
    if [ -n "$state" ] && [ "$state" != Z ]; then
      echo "$pid $(tr '\0' ' ' 2>/dev/null <"/proc/$pid/cmdline")"
    fi
  done
}

downed=0
finish() {
  local rc=$?
  trap - EXIT INT TERM
  if ((!downed)); then
    echo "bringing the cluster down (test ended early)"
    "$cluster_script" down "$cluster" || { echo "FAIL scripts/slurm-cluster down"; rc=1; }
  fi
  local left
  left="$(leftovers)"
  if [ -n "$left" ]; then
    echo "FAIL processes of the cluster left after down (killed now):"
    echo "$left"
    # shellcheck disable=SC2046  # the first word of each line is a pid
    kill -KILL $(echo "$left" | awk '{ print $1 }') 2>/dev/null || true
    rc=1
  fi
  if ((rc != 0)); then
    local log
    for log in "$cluster"/log/*.log; do
      [ -s "$log" ] || continue
      echo "--- last lines of $log:"
      tail -n 20 "$log"
    done
  fi
  rm -rf "$tmp"
  exit "$rc"
}
trap finish EXIT
trap 'exit 130' INT TERM

# --- 1. up --------------------------------------------------------------------------------

started="$(now)"
exports="$("$cluster_script" up "$cluster" --timeout "$deadline_s")"
echo "figure: up took $(seconds_since "$started") s"
check "up prints the line to export ('$exports')" \
  [ "$exports" = "export SLURM_CONF=$cluster/slurm.conf" ]
for name in munged slurmctld slurmd; do
  pid="$(cat "$cluster/run/$name.pid")"
  daemon_start[$pid]="$(start_time "$pid")"
  check "$name runs (pid $pid)" [ -n "${daemon_start[$pid]}" ]
done

again="$("$cluster_script" up "$cluster" 2>"$tmp/again.err")"
said="$(cat "$tmp/again.err")"
check "a second up is a no-op that says so ('$said')" \
  [ "$again" = "$exports" -a "${said/already runs/}" != "$said" ]
"$cluster_script" status "$cluster" >"$tmp/status.out" && status_rc=0 || status_rc=$?
running="$(grep -c ": running (pid" "$tmp/status.out" || true)"
check "status says the three daemons run (exit $status_rc, $running running)" \
  [ "$status_rc" = 0 -a "$running" = 3 ]

# The clients, from a shell of their own that only evaluates what `up` printed.
slurm() { (eval "$exports" && "$@"); }

# --- 2. an array job of 4 tasks -----------------------------------------------------------

cat >"$work/task.sh" <<EOF
#!/bin/bash
# One task: its ids into a file of its own, written whole (a rename) so that a poll never
# reads half of it.
set -eu
file="$work/results/task_\${SLURM_ARRAY_TASK_ID}"
echo "\${SLURM_ARRAY_JOB_ID} \${SLURM_ARRAY_TASK_ID}" >"\$file.partial"
mv "\$file.partial" "\$file"
EOF

started="$(now)"
job="$(slurm sbatch --parsable --array=0-$((tasks - 1)) --chdir="$work" \
  --output="$work/out/%A_%a.out" "$work/task.sh")"
job="${job%%;*}" # --parsable: "id" or "id;cluster"
echo "submitted array job $job"
check "sbatch gives a job id ('$job')" [ -n "$job" -a -z "${job//[0-9]/}" ]

# Done when every task's file is there and none of the job's tasks is in the queue.
end=$((SECONDS + deadline_s))
last=""
while :; do
  files=$(find "$work/results" -name 'task_*' ! -name '*.partial' | wc -l)
  queued="$(slurm squeue -h -j "$job" -o '%i %T' 2>&1 | tr '\n' ' ')" || queued="squeue failed: $queued"
  if ((files == tasks)) && [ -z "$queued" ]; then
    break
  fi
  progress="$files of $tasks files; queue: ${queued:-empty}"
  if [ "$progress" != "$last" ]; then
    echo "waiting: $progress"
    last="$progress"
  fi
  if ((SECONDS >= end)); then
    echo "FAIL the array job did not end with $tasks files in $deadline_s s ($progress)"
    slurm scontrol show job "$job" || true
    exit 1
  fi
  sleep 0.2
done
echo "figure: the $tasks-task array took $(seconds_since "$started") s from sbatch to its last file and an empty queue"

for ((i = 0; i < tasks; i++)); do
  file="$work/results/task_$i"
  content="$(cat "$file" 2>/dev/null || echo "(no file)")"
  check "task $i wrote its array job id and task id ('$content')" [ "$content" = "$job $i" ]
done
records="$(slurm scontrol -o show job "$job")"
known="$(grep -c "ArrayJobId=$job " <<<"$records" || true)"
check "scontrol knows $tasks tasks of job $job ($known)" [ "$known" = "$tasks" ]
for ((i = 0; i < tasks; i++)); do
  record="$(grep "ArrayJobId=$job ArrayTaskId=$i " <<<"$records" || true)"
  state="$(grep -o 'JobState=[^ ]*' <<<"$record" || true) $(grep -o 'ExitCode=[^ ]*' <<<"$record" || true)"
  check "task $i: $state" [ "$state" = "JobState=COMPLETED ExitCode=0:0" ]
done

# --- 3. down ------------------------------------------------------------------------------

started="$(now)"
"$cluster_script" down "$cluster" && down_rc=0 || down_rc=$?
downed=1
echo "figure: down took $(seconds_since "$started") s"
check "down exits 0 (exit $down_rc)" [ "$down_rc" = 0 ]
left="$(leftovers)"
check "no process of the cluster is left after down${left:+: $left}" [ -z "$left" ]
"$cluster_script" status "$cluster" >"$tmp/status.out" && status_rc=0 || status_rc=$?
check "status says nothing runs (exit $status_rc)" [ "$status_rc" = 3 ]

if ((failures)); then
  echo "$failures check(s) failed"
  exit 1
fi
echo "OK: the one-node cluster ran a $tasks-task array job and left nothing"
