#!/usr/bin/env bash
# Proves that the throw-away Slurm cluster of cluster.sh does what a sharded sweep needs, on a
# real Slurm (no mock): job arrays run one task per index, a dependent job starts only after
# every task ended well, and a task that fails once is requeued and then succeeds. Measures
# the cluster's start-up time and the overhead per array task.
#
#   sudo tests/slurm/test_cluster.sh
#
# Installs the Debian packages when missing; fails (never skips) when the cluster cannot start.
# The cluster is stopped and its state removed on exit, whatever happens.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/slurm/cluster.sh
source "$here/cluster.sh"
trap slurm_stop EXIT

t=$(now)
slurm_install
install_s=$(elapsed "$t" "$(now)")
t=$(now)
slurm_start || fail "the cluster did not start"
startup_s=$(elapsed "$t" "$(now)")
echo "cluster up: node $SLURM_NODE idle after ${startup_s} s (install step ${install_s} s)"
jobs_dir=$SLURM_TEST_DIR/jobs
cpus=$(sinfo -h -N -o '%c')

# --- 1. A job array of 4 tasks, and a job that depends on all of them (afterok).
# shellcheck disable=SC2016 # expanded by the job, not here
array=$(sbatch --parsable --array=0-3 --output="$jobs_dir/array_%a.out" \
  --wrap 'sleep 1; echo "$SLURM_ARRAY_TASK_ID"; date +%s.%N')
after=$(sbatch --parsable --dependency="afterok:$array" --output="$jobs_dir/after.out" \
  --wrap 'date +%s.%N')
reason=$(squeue -h -j "$after" -o '%r')
[ "$reason" = "Dependency" ] || fail "the dependent job should wait on its dependency, squeue says '$reason'"
slurm_wait_jobs 60 "$array" "$after" || fail "array $array or dependent job $after did not end"
last_end=0
for i in 0 1 2 3; do
  state=$(slurm_job_states "${array}_$i" | awk '{ print $2 }')
  [ "$state" = COMPLETED ] || fail "array task $i: state $state, expected COMPLETED"
  out=$jobs_dir/array_$i.out
  [ "$(sed -n 1p "$out")" = "$i" ] || fail "array task $i printed '$(sed -n 1p "$out")'"
  last_end=$(awk -v a="$last_end" -v b="$(sed -n 2p "$out")" 'BEGIN { print (b > a) ? b : a }')
done
[ "$(slurm_job_states "$after" | awk '{ print $2 }')" = COMPLETED ] || fail "the dependent job did not complete"
after_start=$(cat "$jobs_dir/after.out")
awk -v s="$after_start" -v e="$last_end" 'BEGIN { exit !(s > e) }' ||
  fail "the dependent job started at $after_start, before the last task ended at $last_end"
echo "array of 4 tasks: each printed its index; the afterok job started $(elapsed "$last_end" "$after_start") s after the last task ended"

# --- 2a. A task that fails on its first attempt, requeued from outside, then succeeds.
# An afterok job on that array is never released (Slurm marks it DependencyNeverSatisfied
# when the task fails, and a later requeue does not undo that).
# shellcheck disable=SC2016 # expanded by the job, not here
flaky=$(sbatch --parsable --requeue --array=0-3 --open-mode=append \
  --output="$jobs_dir/flaky_%a.out" --wrap '
    echo "task $SLURM_ARRAY_TASK_ID attempt ${SLURM_RESTART_COUNT:-0}"
    if [ "$SLURM_ARRAY_TASK_ID" = 2 ] && [ "${SLURM_RESTART_COUNT:-0}" = 0 ]; then exit 3; fi')
stuck=$(sbatch --parsable --dependency="afterok:$flaky" --output=/dev/null --wrap true)
slurm_wait_jobs 60 "$flaky" || fail "the flaky array did not end"
for i in 0 1 3; do
  state=$(slurm_job_states "${flaky}_$i" | awk '{ print $2 }')
  [ "$state" = COMPLETED ] || fail "flaky task $i: state $state, expected COMPLETED"
done
state=$(slurm_job_states "${flaky}_2" | awk '{ print $2 }')
[ "$state" = FAILED ] || fail "flaky task 2: state $state on its first attempt, expected FAILED"
slurm_wait_for 30 bash -c "[ \"\$(squeue -h -j $stuck -o %r)\" = DependencyNeverSatisfied ]" ||
  fail "the afterok job of an array with a failed task: $(squeue -h -j "$stuck" -o '%T %r')"
t=$(now)
scontrol requeue "${flaky}_2"
# The requeued task goes back to PENDING; it may start again once its previous credential
# expired (AuthInfo cred_expire: 10 s here, 120 s by Slurm's default).
slurm_wait_for 30 bash -c "! squeue -h -r --states=all -j ${flaky}_2 -o %T | grep -qx FAILED" ||
  fail "task ${flaky}_2 was not requeued"
slurm_wait_jobs 300 "${flaky}_2" || fail "the requeued task did not end"
requeue_s=$(elapsed "$t" "$(now)")
state=$(slurm_job_states "${flaky}_2" | awk '{ print $2 }')
[ "$state" = COMPLETED ] || fail "requeued task 2: state $state, expected COMPLETED"
expected=$'task 2 attempt 0\ntask 2 attempt 1'
[ "$(cat "$jobs_dir/flaky_2.out")" = "$expected" ] ||
  fail "requeued task's output: $(cat "$jobs_dir/flaky_2.out")"
[ "$(squeue -h -j "$stuck" -o %r)" = DependencyNeverSatisfied ] ||
  fail "the afterok job was released after the requeue: $(squeue -h -j "$stuck" -o '%T %r')"
scancel "$stuck"
echo "task 2 failed on attempt 0 (exit 3), was requeued by scontrol and completed on attempt 1 after ${requeue_s} s; the afterok job stayed DependencyNeverSatisfied"

# --- 2b. A task that requeues itself when its first attempt fails: the afterok job waits for
# the rerun and then runs (the pattern for a sweep's array task and its dependent merge job).
# shellcheck disable=SC2016 # expanded by the job, not here
selfq=$(sbatch --parsable --requeue --array=0-3 --open-mode=append \
  --output="$jobs_dir/selfq_%a.out" --wrap '
    attempt=${SLURM_RESTART_COUNT:-0}
    echo "task $SLURM_ARRAY_TASK_ID attempt $attempt"
    if [ "$SLURM_ARRAY_TASK_ID" = 2 ] && [ "$attempt" = 0 ]; then
      # The work failed: requeue this task (Slurm ends this attempt right away).
      scontrol requeue "${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}"
      sleep 60
      exit 1
    fi
    date +%s.%N')
merge=$(sbatch --parsable --dependency="afterok:$selfq" --output="$jobs_dir/merge.out" \
  --wrap 'date +%s.%N')
t=$(now)
slurm_wait_jobs 300 "$selfq" "$merge" || fail "the self-requeuing array or its afterok job did not end"
selfq_s=$(elapsed "$t" "$(now)")
for i in 0 1 2 3; do
  state=$(slurm_job_states "${selfq}_$i" | awk '{ print $2 }')
  [ "$state" = COMPLETED ] || fail "self-requeuing task $i: state $state, expected COMPLETED"
done
[ "$(slurm_job_states "$merge" | awk '{ print $2 }')" = COMPLETED ] ||
  fail "the afterok job of the self-requeuing array did not complete"
attempts=$(grep '^task 2 attempt' "$jobs_dir/selfq_2.out" | tr '\n' ';')
[ "$attempts" = "task 2 attempt 0;task 2 attempt 1;" ] ||
  fail "task 2 did not run twice: $(cat "$jobs_dir/selfq_2.out")"
rerun_end=$(tail -n 1 "$jobs_dir/selfq_2.out")
awk -v s="$(cat "$jobs_dir/merge.out")" -v e="$rerun_end" 'BEGIN { exit !(s > e) }' ||
  fail "the afterok job started before the rerun of task 2 ended"
echo "task 2 requeued itself after attempt 0; the afterok job ran after attempt 1 (array + job ${selfq_s} s)"

# --- 3. Overheads: one empty job, submit to end; an array of 32 empty tasks, submit to end.
t=$(now)
single=$(sbatch --parsable --output=/dev/null --wrap true)
slurm_wait_jobs 60 "$single" || fail "an empty job did not end"
single_s=$(elapsed "$t" "$(now)")
t=$(now)
many=$(sbatch --parsable --array=0-31 --output=/dev/null --wrap true)
slurm_wait_jobs 300 "$many" || fail "the array of 32 empty tasks did not end"
many_s=$(elapsed "$t" "$(now)")
per_task=$(awk -v w="$many_s" 'BEGIN { printf "%.3f", w / 32 }')
bad=$(slurm_job_states "$many" | grep -vc ' COMPLETED$' || true)
[ "$bad" = 0 ] || fail "$bad of the 32 empty tasks did not complete"

echo
echo "== figures (node with $cpus CPU slots on $(nproc) cores)"
echo "install step (apt-get only if missing)         ${install_s} s"
echo "cluster start-up (munged → node idle)          ${startup_s} s"
echo "one empty job, sbatch → end                    ${single_s} s"
echo "array of 32 empty tasks, sbatch → all ended    ${many_s} s (${per_task} s per task)"
echo "requeue of a failed task → completed           ${requeue_s} s (cred_expire=${SPURIO_SLURM_CRED_EXPIRE:-10} s)"
echo "self-requeuing array of 4 + afterok job         ${selfq_s} s"

# --- 4. Teardown leaves nothing behind: no daemon, no slurmstepd of this cluster, no folder.
dir=$SLURM_TEST_DIR
pids=("${SLURM_TEST_PIDS[@]}")
t=$(now)
slurm_stop
teardown_s=$(elapsed "$t" "$(now)")
for pid in "${pids[@]}"; do
  slurm_pid_gone "$pid" || fail "daemon $pid still runs after slurm_stop"
done
SLURM_TEST_DIR=$dir
left=$(slurm_stepd_pids)
SLURM_TEST_DIR=""
[ -z "$left" ] || fail "slurmstepd processes left: $left"
[ ! -e "$dir" ] || fail "$dir still exists after slurm_stop"
echo "teardown in ${teardown_s} s: ${#pids[@]} daemons stopped, no slurmstepd left, $dir removed"
echo "PASS"
