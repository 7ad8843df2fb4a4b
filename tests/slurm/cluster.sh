# shellcheck shell=bash
# A throw-away single-node Slurm cluster on this machine, for tests: source this file, then
#
#   trap slurm_stop EXIT
#   slurm_install            # apt-get the Debian 12 packages if missing (idempotent)
#   slurm_start              # munged, slurmctld, slurmd in the background; waits for `idle`
#   sbatch --array=0-3 …     # SLURM_CONF is exported, the client commands find the cluster
#
# Everything the cluster writes lives in one temporary folder ($SLURM_TEST_DIR: config, munge
# key and socket, controller state, slurmd spool, logs, job output), nothing under /etc or
# /var: the Debian packages are used for their binaries only. The daemons run as root (as
# CI does), each started here and stopped by its process id. `slurm_stop` cancels the jobs,
# stops the daemons and removes the folder (keeping the logs on request, see below).
#
# Settings (environment, all optional):
#   SPURIO_SLURM_CPUS        CPUs the node announces (default 8; more than the machine has is
#                            fine: jobs are short and a CPU here is a job slot)
#   SPURIO_SLURM_CTLD_PORT   slurmctld port (default 6817)
#   SPURIO_SLURM_SLURMD_PORT slurmd port (default 6818)
#   SPURIO_SLURM_KEEP_LOGS   a folder to copy the daemons' logs into when the cluster stops
#   SPURIO_SLURM_CRED_EXPIRE seconds a requeued job waits before it may start again (default
#                            10; Slurm's own default is 120)
#
# Needs root (the daemons, apt-get). Bash only.

SLURM_PACKAGES=(munge slurmctld slurmd slurm-client)
SLURM_TEST_DIR=""
SLURM_TEST_PIDS=()
SLURM_NODE=""

slurm_log() { echo "slurm-test: $*" >&2; }

# For the test scripts: a failure that shows the daemons' logs first, and wall-clock timing
# (`t=$(now); …; echo "$(elapsed "$t" "$(now)") s"`).
fail() {
  echo "FAIL: $*" >&2
  slurm_dump_logs
  exit 1
}
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", b - a }'; }

# Installs the Debian packages when a binary is missing. Daemons the packages' scripts might
# start are not ours and not needed: the cluster below uses its own key, socket and ports.
slurm_install() {
  local missing=() p
  for p in "${SLURM_PACKAGES[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
  for p in munged mungekey slurmctld slurmd sbatch squeue sinfo scontrol scancel; do
    command -v "$p" >/dev/null 2>&1 || { [ -x "/usr/sbin/$p" ] || missing+=("(binary $p)"); }
  done
  if ((${#missing[@]} == 0)); then
    return 0
  fi
  if [ "$(id -u)" -ne 0 ]; then
    slurm_log "must run as root to install ${missing[*]}"
    return 1
  fi
  slurm_log "installing ${SLURM_PACKAGES[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${SLURM_PACKAGES[@]}" >/dev/null
}

# True when something already listens on TCP port $1 on this machine.
slurm_port_busy() {
  (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null
}

# Waits up to $1 seconds for the command "${@:2}" to succeed.
slurm_wait_for() {
  local timeout=$1 start=$SECONDS
  shift
  until "$@"; do
    if ((SECONDS - start >= timeout)); then
      return 1
    fi
    sleep 0.2
  done
}

slurm_node_idle() {
  [ "$(sinfo -h -N -n "$SLURM_NODE" -o '%T' 2>/dev/null)" = "idle" ]
}

# Starts munged, slurmctld and slurmd, waits until the node is idle. Sets SLURM_TEST_DIR and
# exports SLURM_CONF. Returns non-zero (after printing the logs) if the cluster does not come up.
slurm_start() {
  if [ "$(id -u)" -ne 0 ]; then
    slurm_log "the test cluster runs its daemons as root; run as root"
    return 1
  fi
  local cpus=${SPURIO_SLURM_CPUS:-8}
  local ctld_port=${SPURIO_SLURM_CTLD_PORT:-6817}
  local slurmd_port=${SPURIO_SLURM_SLURMD_PORT:-6818}
  local port
  for port in "$ctld_port" "$slurmd_port"; do
    if slurm_port_busy "$port"; then
      slurm_log "port $port is already in use (another Slurm?); set SPURIO_SLURM_CTLD_PORT/SPURIO_SLURM_SLURMD_PORT"
      return 1
    fi
  done
  SLURM_TEST_DIR=$(mktemp -d /tmp/spurio-slurm.XXXXXX)
  chmod 0755 "$SLURM_TEST_DIR" # job output is read back by the caller
  local d=$SLURM_TEST_DIR
  mkdir -p "$d/munge" "$d/state" "$d/spool" "$d/log" "$d/jobs"
  chmod 0700 "$d/munge"
  SLURM_NODE=$(hostname -s)

  # munge: our own key and socket, so a system munged (if any) is neither used nor disturbed.
  mungekey --create --keyfile="$d/munge/munge.key" --force
  chmod 0400 "$d/munge/munge.key"
  munged --foreground --force \
    --socket="$d/munge/munge.socket.2" --key-file="$d/munge/munge.key" \
    --pid-file="$d/munge/munged.pid" --seed-file="$d/munge/munged.seed" \
    --log-file="$d/log/munged.log" >"$d/log/munged.out" 2>&1 &
  SLURM_TEST_PIDS+=($!)
  if ! slurm_wait_for 10 test -S "$d/munge/munge.socket.2"; then
    slurm_log "munged did not start"
    slurm_dump_logs
    return 1
  fi

  cat >"$d/slurm.conf" <<EOF
# A single-node cluster for tests (written by tests/slurm/cluster.sh).
ClusterName=spurio-test
SlurmctldHost=$SLURM_NODE(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$d/munge/munge.socket.2,cred_expire=${SPURIO_SLURM_CRED_EXPIRE:-10}
CredType=cred/munge
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/log/slurmctld.log
SlurmdLogFile=$d/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
PlugStackConfig=$d/plugstack.conf
# No cgroups in containers: plain process tracking, no task binding, no accounting daemon.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
# The node announces the CPUs configured here, not the ones it finds.
SlurmdParameters=config_overrides
ReturnToService=2
JobRequeue=1
# Finished jobs stay visible to squeue/scontrol for an hour (no accounting database here).
MinJobAge=3600
KillWait=5
NodeName=$SLURM_NODE NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=1000 State=UNKNOWN
PartitionName=debug Nodes=$SLURM_NODE Default=YES MaxTime=INFINITE State=UP
EOF
  : >"$d/plugstack.conf"
  export SLURM_CONF="$d/slurm.conf"

  slurmctld -D -c -f "$SLURM_CONF" >"$d/log/slurmctld.out" 2>&1 &
  SLURM_TEST_PIDS+=($!)
  slurmd -D -f "$SLURM_CONF" -N "$SLURM_NODE" >"$d/log/slurmd.out" 2>&1 &
  SLURM_TEST_PIDS+=($!)
  if ! slurm_wait_for 60 slurm_node_idle; then
    slurm_log "the node did not become idle within 60 s"
    sinfo -N -l >&2 || true
    slurm_dump_logs
    return 1
  fi
}

slurm_dump_logs() {
  local f
  for f in "$SLURM_TEST_DIR"/log/*; do
    [ -s "$f" ] || continue
    echo "----- $f (last 30 lines)" >&2
    tail -n 30 "$f" >&2
  done
}

# One line "<job id> <state>" per job or array task of the given job ids (finished ones too).
slurm_job_states() {
  local ids
  ids=$(
    IFS=,
    echo "$*"
  )
  squeue -h -r --states=all -j "$ids" -o '%i %T' 2>/dev/null
}

# True when every job/task of the given ids has reached a state that ends it.
slurm_jobs_ended() {
  local states
  states=$(slurm_job_states "$@") || return 1
  [ -n "$states" ] || return 1
  ! grep -Ev ' (COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|BOOT_FAIL|DEADLINE|PREEMPTED)$' <<<"$states" >/dev/null
}

# Waits up to $1 seconds until all of the job ids "${@:2}" ended.
slurm_wait_jobs() {
  local timeout=$1
  shift
  if ! slurm_wait_for "$timeout" slurm_jobs_ended "$@"; then
    slurm_log "jobs $* did not end within $timeout s:"
    slurm_job_states "$@" >&2
    return 1
  fi
}

# Cancels the jobs, stops the daemons we started (by process id) and removes the folder.
# Safe to call more than once and when slurm_start failed half-way.
slurm_stop() {
  local status=$?
  if [ -n "$SLURM_TEST_DIR" ] && [ -n "${SLURM_CONF:-}" ] && [ -f "$SLURM_CONF" ]; then
    local jobs
    jobs=$(squeue -h -o '%i' 2>/dev/null | tr '\n' ' ')
    if [ -n "${jobs// /}" ]; then
      # shellcheck disable=SC2086
      scancel $jobs 2>/dev/null || true
      slurm_wait_for 20 test -z "$(squeue -h -o '%i' 2>/dev/null)" || true
    fi
  fi
  # A job's slurmstepd lingers a moment after the job ended, reporting to slurmd; let it
  # finish before slurmd goes, and end any left afterwards (ours: they carry our SLURM_CONF).
  slurm_wait_for 30 slurm_no_stepd || true
  local pid i
  for ((i = ${#SLURM_TEST_PIDS[@]} - 1; i >= 0; i--)); do
    pid=${SLURM_TEST_PIDS[i]}
    kill -TERM "$pid" 2>/dev/null || continue
    slurm_wait_for 15 slurm_pid_gone "$pid" || kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  SLURM_TEST_PIDS=()
  for pid in $(slurm_stepd_pids); do
    kill -KILL "$pid" 2>/dev/null || true
  done
  if [ -n "$SLURM_TEST_DIR" ] && [ -d "$SLURM_TEST_DIR" ]; then
    if [ -n "${SPURIO_SLURM_KEEP_LOGS:-}" ]; then
      mkdir -p "$SPURIO_SLURM_KEEP_LOGS"
      cp -r "$SLURM_TEST_DIR/log/." "$SPURIO_SLURM_KEEP_LOGS/" 2>/dev/null || true
    fi
    rm -rf "$SLURM_TEST_DIR"
  fi
  SLURM_TEST_DIR=""
  unset SLURM_CONF
  return "$status"
}

# True when process $1 has ended (an unreaped child of this shell counts as ended).
slurm_pid_gone() {
  local stat
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 0
  stat=${stat##*) }
  [ "${stat%% *}" = Z ]
}

# The process ids of the slurmstepd processes of this cluster (those whose environment holds
# this cluster's SLURM_CONF, inherited from our slurmd).
slurm_stepd_pids() {
  [ -n "$SLURM_TEST_DIR" ] || return 0
  local proc
  for proc in /proc/[0-9]*; do
    [ "$(cat "$proc/comm" 2>/dev/null)" = slurmstepd ] || continue
    if tr '\0' '\n' 2>/dev/null <"$proc/environ" |
      grep -qxF "SLURM_CONF=$SLURM_TEST_DIR/slurm.conf"; then
      echo "${proc#/proc/}"
    fi
  done
}

slurm_no_stepd() {
  [ -z "$(slurm_stepd_pids)" ]
}
