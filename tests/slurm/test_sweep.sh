#!/usr/bin/env bash
# A sweep on a real Slurm cluster (cluster.sh, no mock) gives the one-machine table byte for
# byte: `spurio sweep --slurm <dir> --shards 5 --submit` stages the crane + sensor system of
# examples/systems/crane_sensor.toml with 100 seeds, submits a job array of 5 shards and a
# merge job (afterok), and the merged table.md and runs.csv must equal the output of
# `spurio sweep … --out` on this machine. Done twice: once as it is, once with array task 2
# made to fail on its first attempt (the batch script's test hook, a file
# <dir>/inject-failure/2), which must requeue itself and let the merge job run after its rerun.
# Prints the local and Slurm wall times and the overhead per array task.
#
#   sudo tests/slurm/test_sweep.sh          (after scripts/build-fmus)
#
# Installs the Slurm packages when missing; fails, never skips, when the cluster cannot start.
# The cluster and everything the sweep wrote are removed on exit.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
# shellcheck source=tests/slurm/cluster.sh
source "$here/cluster.sh"
trap slurm_stop EXIT

spurio=${SPURIO:-$repo/target/release/spurio}
system=$repo/examples/systems/crane_sensor.toml
[ -x "$spurio" ] || fail "$spurio not found: run scripts/build-fmus first"
[ -f "$repo/build/fmus/GantryCrane.fmu" ] || fail "build/fmus/ is empty: run scripts/build-fmus first"
shards=5
runs=100
sweep=("$system" --vary "sensor.seed=1..$runs"
  --metric 'rms(sensor.y[1])' --metric 'e_res(sensor.y[2], crane.theta)'
  --metric 'max_abs(sensor.y[1])')

slurm_install
slurm_start || fail "the cluster did not start"
work=$SLURM_TEST_DIR/sweep # removed with the cluster
mkdir -p "$work"

# --- The one-machine sweep (all cores of this machine).
t=$(now)
"$spurio" sweep "${sweep[@]}" --out "$work/local.csv" >"$work/local.md"
local_s=$(elapsed "$t" "$(now)")
[ "$(grep -c '| 100/100 |' "$work/local.md")" = 3 ] || fail "local sweep table: $(cat "$work/local.md")"
[ "$(wc -l <"$work/local.csv")" = $((runs + 1)) ] || fail "local sweep: $(wc -l <"$work/local.csv") CSV lines"

# Stages and submits a sweep into $1, waits for the array and the merge job, checks the
# result against the local sweep. Sets array, merge, slurm_s.
run_on_slurm() {
  local dir=$1 out
  t=$(now)
  out=$("$spurio" sweep "${sweep[@]}" --slurm "$dir" --shards "$shards" --time 00:10:00 --submit) ||
    fail "spurio sweep --slurm --submit failed: $out"
  local line
  while IFS= read -r line; do echo "  | $line"; done <<<"$out"
  array=$(sed -n 's/^submitted array job \([0-9]*\) .*/\1/p' <<<"$out")
  merge=$(sed -n 's/.* and merge job \([0-9]*\) (afterok:.*/\1/p' <<<"$out")
  if [ -z "$array" ] || [ -z "$merge" ]; then fail "no job ids in: $out"; fi
  slurm_wait_jobs 300 "$array" "$merge" || fail "the sweep's jobs did not end"
  slurm_s=$(elapsed "$t" "$(now)")
  local i state
  for ((i = 0; i < shards; i++)); do
    state=$(slurm_job_states "${array}_$i" | awk '{ print $2 }')
    [ "$state" = COMPLETED ] || fail "array task $i: $state; log: $(cat "$dir/logs/shard-$i.out" 2>/dev/null)"
  done
  state=$(slurm_job_states "$merge" | awk '{ print $2 }')
  [ "$state" = COMPLETED ] || fail "merge job: $state; log: $(cat "$dir/logs/merge.out" 2>/dev/null)"
  cmp "$dir/table.md" "$work/local.md" ||
    fail "the Slurm table differs from the local one:$(diff "$dir/table.md" "$work/local.md")"
  cmp "$dir/runs.csv" "$work/local.csv" || fail "the Slurm runs.csv differs from the local one"
  local progress
  progress=$("$spurio" sweep-merge --progress "$dir") || fail "sweep-merge --progress failed"
  progress=${progress%%$'\n'*}
  [ "$progress" = "$shards/$shards shards done ($runs/$runs runs)" ] || fail "progress: $progress"
}

# Seconds from the first task's start to the last task's end, from the tasks' logs.
task_span() {
  cat "$1"/logs/shard-*.out | awk '
    / start / { s = $NF; if (first == "" || s < first) first = s }
    / end / { e = $(NF - 2); if (e > last) last = e }
    END { printf "%.2f", last - first }'
}

# --- 1. The sweep as it is.
echo "sweep of $runs runs in $shards array tasks:"
run_on_slurm "$work/clean"
clean_s=$slurm_s
clean_span=$(task_span "$work/clean")
echo "table.md and runs.csv equal the local sweep's, byte for byte"

# --- 2. The same sweep, array task 2 failing on its first attempt.
echo "the same, array task 2 failing once:"
mkdir -p "$work/faulty/inject-failure"
: >"$work/faulty/inject-failure/2"
run_on_slurm "$work/faulty"
faulty_s=$slurm_s
log=$work/faulty/logs/shard-2.out
attempts=$(grep -c '^shard 2/5 attempt [0-9]* on ' "$log" || true)
[ "$attempts" = 2 ] || fail "task 2 ran $attempts times: $(cat "$log")"
grep -q '^shard 2: injected failure' "$log" || fail "task 2 did not fail: $(cat "$log")"
grep -q '^shard 2: attempt 0 failed (exit 75), requeueing' "$log" || fail "task 2 did not requeue itself: $(cat "$log")"
grep -q '^shard 2 attempt 1 end .* exit 0$' "$log" || fail "task 2's rerun did not succeed: $(cat "$log")"
[ ! -e "$work/faulty/inject-failure/2" ] || fail "the failure marker is still there"
requeue_s=$(awk '/^shard 2 attempt 0 end / { e = $(NF - 2) } /^shard 2\/5 attempt 1 on / { s = $NF }
  END { printf "%.2f", s - e }' "$log")
echo "task 2 failed on attempt 0, requeued itself, ran again ${requeue_s} s later; the merge job then ran"

overhead=$(awk -v w="$clean_s" -v l="$local_s" 'BEGIN { printf "%.2f", w - l }')
per_task=$(awk -v o="$overhead" -v n="$shards" 'BEGIN { printf "%.2f", o / n }')
echo
echo "== figures ($runs runs, $shards array tasks, node with $(sinfo -h -N -o '%c') CPU slots on $(nproc) cores)"
echo "local spurio sweep (all cores)                   ${local_s} s"
echo "Slurm: stage + submit → merge job ended          ${clean_s} s (tasks' own span ${clean_span} s)"
echo "Slurm overhead (Slurm − local), per array task   ${overhead} s, ${per_task} s per task"
echo "Slurm with task 2 failing once and requeued      ${faulty_s} s (rerun started ${requeue_s} s after the failure)"
echo "PASS"
