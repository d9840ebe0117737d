#!/bin/bash
# Runs the SLURM recipes for real on a one-node SLURM on this machine (Debian's slurm-wlm:
# munged, slurmctld and slurmd on localhost, configured in a temporary directory through
# SLURM_CONF; /etc/slurm is not touched), then stops the daemons it started (by their PIDs):
#   apt-get install slurm-wlm            # once, as root
#   PENUMBRA=target/release/penumbra deploy/slurm/localhost-run.sh
# It submits submit-frame.sh twice (7 tile parts of ratio; 4 sample ranges of directlighting)
# and submit-sweep.sh once, waits for the jobs, and compares the merged frames with single
# renders (cmp) and the collected sweep with an ordinary one (rows without timings).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
PENUMBRA=$(cd "$(dirname "${PENUMBRA:-$repo/target/release/penumbra}")" && pwd)/$(basename "${PENUMBRA:-penumbra}")
export PENUMBRA
work=${WORK:-$(mktemp -d /tmp/penumbra-slurm.XXXXXX)}
mkdir -p "$work"/{spool,state,log}
node=$(hostname -s)
cpus=$(nproc)
cat > "$work/slurm.conf" <<CONF
ClusterName=penumbra
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
ReturnToService=2
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmdSpoolDir=$work/spool
StateSaveLocation=$work/state
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$work/slurm.conf
pids=()
stop() { # the daemons this script started, by PID; waits for them to shut down
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for _ in $(seq 40); do
        alive=0
        for p in "${pids[@]}"; do
            if [ -d "/proc/$p" ] && ! grep -q '^State:.*Z' "/proc/$p/status" 2>/dev/null; then alive=1; fi
        done
        [ "$alive" = 0 ] && return
        sleep 0.25
    done
}
trap stop EXIT
if ! pgrep -x munged >/dev/null; then
    mkdir -p /run/munge && chown munge:munge /run/munge
    runuser -u munge -- /usr/sbin/munged
    for _ in $(seq 20); do [ -s /run/munge/munged.pid ] && break; sleep 0.5; done
    pids+=("$(cat /run/munge/munged.pid)")
fi
/usr/sbin/slurmctld -f "$SLURM_CONF"
sleep 1
pids+=("$(cat "$work/slurmctld.pid")")
/usr/sbin/slurmd -f "$SLURM_CONF"
sleep 2
pids+=("$(cat "$work/slurmd.pid")")
for _ in $(seq 30); do
    sinfo -h -o '%T' | grep -qE 'idle|mixed' && break
    sleep 1
done
sinfo

wait_for_jobs() {
    for _ in $(seq 600); do
        [ -z "$(squeue -h -o %i)" ] && return 0
        sleep 1
    done
    echo "jobs did not finish" >&2
    squeue
    return 1
}
scene=$work/scene.pbrt
cp "$repo/scenes/suite/ltc/two-lights-metal.pbrt" "$scene"
small="--resolution 48x40"
SBATCH_ARGS="--cpus-per-task=1" SCENE=$scene PARTS=7 OUT=$work/frame INTEGRATOR=ratio SPP=4 RENDER_ARGS=$small \
    "$here/submit-frame.sh"
SBATCH_ARGS="--cpus-per-task=1" SCENE=$scene PARTS=4 SPLIT=samples SPP=8 OUT=$work/ref INTEGRATOR=directlighting \
    RENDER_ARGS=$small "$here/submit-frame.sh"
SBATCH_ARGS="--cpus-per-task=1" OUT=$work/sweep \
    SWEEP_ARGS="$scene -i directlighting,ltc --reference-spp 64 --budgets 1,4,16 --resolution 24x24 --threads 1" \
    "$here/submit-sweep.sh"
squeue
wait_for_jobs
"$PENUMBRA" render "$scene" -i ratio --spp 4 $small -q -o "$work/frame-single.exr"
"$PENUMBRA" render "$scene" -i directlighting --spp 32 $small -q -o "$work/ref-single.exr"
status=0
check() { # check WHAT COMMAND…: prints WHAT when COMMAND succeeds, else fails the run
    local what=$1
    shift
    if "$@"; then echo "$what"; else echo "FAILED: $what" >&2; status=1; fi
}
check "frame: 7 SLURM tasks merged = single render (byte for byte)" cmp "$work/frame/frame.exr" "$work/frame-single.exr"
check "reference: 4 x 8 spp SLURM tasks merged = 32-spp render (byte for byte)" cmp "$work/ref/frame.exr" "$work/ref-single.exr"
"$PENUMBRA" sweep "$scene" -i directlighting,ltc --reference-spp 64 --budgets 1,4,16 --resolution 24x24 --threads 1 -q -o "$work/sweep-plain" >/dev/null
cut -d, -f1,2,6- "$work/sweep/sweep.csv" > "$work/sweep-untimed.csv"
cut -d, -f1,2,6- "$work/sweep-plain/sweep.csv" > "$work/sweep-plain-untimed.csv"
check "sweep: $(($(wc -l < "$work/sweep/sweep.csv") - 1)) rows collected from SLURM items = the ordinary sweep's (timings aside)" \
    cmp "$work/sweep-untimed.csv" "$work/sweep-plain-untimed.csv"
grep -h "hostname" "$work"/sweep/items/*.json | sort | uniq -c
echo "logs and outputs in $work"
exit $status
