#!/usr/bin/env bash
# test_slurm.sh RBCLOTH MESH_DIR SLURM_SAMPLES WORK_DIR
# A one-node Slurm on localhost (munged, slurmctld, slurmd, all as root, with their
# own key, socket, ports, state and spool under WORK_DIR) runs a 2-entry manifest
# through samples/slurm/submit.sh: an array of 2 tasks and the merge step; the
# merged report must list both jobs ok. Where Slurm cannot start (not root, the
# slurm-wlm or munge packages missing, a daemon that does not come up) the test
# says why and exits 77, which CTest reports as skipped. Every wait is bounded and
# the daemons are always stopped (trap).
set -uo pipefail
RBCLOTH=$1 MESH_DIR=$2 SAMPLES=$3 WORK=$4
skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*"; show_logs; exit 1; }
show_logs() {
  for f in "$WORK"/munged.log "$WORK"/slurmctld.log "$WORK"/slurmd.log "$WORK"/out/slurm-*.log; do
    [ -f "$f" ] && { echo "--- $f (last 15 lines)"; tail -n 15 "$f"; }
  done
}

[ "$(id -u)" -eq 0 ] || skip "needs root to run slurmd (run as root, or see samples/slurm/README.md)"
for c in munged mungekey slurmctld slurmd sbatch sinfo squeue scancel timeout; do
  command -v "$c" > /dev/null || skip "'$c' not found (Debian packages slurm-wlm and munge)"
done

rm -rf "$WORK" && mkdir -p "$WORK"/ctld "$WORK"/slurmd "$WORK"/munge "$WORK"/out || fail "cannot create $WORK"
chmod 700 "$WORK"/munge
pids=()
cleanup() {
  if [ -n "${SLURM_CONF:-}" ] && [ -f "$SLURM_CONF" ]; then
    timeout 5 scancel --quiet --user=root > /dev/null 2>&1 || true
  fi
  # Daemons in reverse order of start, by the pids this script recorded.
  for ((k = ${#pids[@]} - 1; k >= 0; k--)); do kill "${pids[k]}" 2> /dev/null || true; done
  for _ in $(seq 50); do
    alive=0
    for p in "${pids[@]}"; do kill -0 "$p" 2> /dev/null && alive=1; done
    [ $alive -eq 0 ] && break
    sleep 0.1
  done
  for p in "${pids[@]}"; do kill -9 "$p" 2> /dev/null || true; done
}
trap cleanup EXIT
trap 'exit 1' INT TERM

# munge: a fresh key and a private socket.
key=$WORK/munge/munge.key
timeout 10 mungekey --create --keyfile="$key" 2> /dev/null ||
  { dd if=/dev/urandom of="$key" bs=1024 count=1 status=none && chmod 400 "$key"; } ||
  skip "cannot create a munge key"
sock=$WORK/munge/munge.socket
munged --foreground --force --key-file="$key" --socket="$sock" --pid-file="$WORK/munge/munged.pid" \
  --seed-file="$WORK/munge/munged.seed" --log-file="$WORK/munged.log" > /dev/null 2>&1 &
pids+=($!)
for _ in $(seq 50); do [ -S "$sock" ] && break; sleep 0.1; done
[ -S "$sock" ] || { show_logs; skip "munged did not start"; }

# Slurm: one node, this host, random ports (tests may run beside a real Slurm).
host=$(hostname -s)
port=$((20000 + RANDOM % 20000))
export SLURM_CONF=$WORK/slurm.conf
cat > "$SLURM_CONF" << CONF
ClusterName=rbcloth-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
StateSaveLocation=$WORK/ctld
SlurmdSpoolDir=$WORK/slurmd
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/slurmctld.log
SlurmdLogFile=$WORK/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MaxJobCount=1000
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=rbcloth Nodes=$host Default=YES MaxTime=10 State=UP
CONF
slurmctld -D -i -f "$SLURM_CONF" > "$WORK/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N "$host" -f "$SLURM_CONF" > "$WORK/slurmd.out" 2>&1 &
pids+=($!)
state=""
for _ in $(seq 60); do
  state=$(timeout 3 sinfo -h -N -o '%T' 2> /dev/null | head -n 1)
  [ "$state" = "idle" ] && break
  for p in "${pids[@]}"; do kill -0 "$p" 2> /dev/null || { cat "$WORK"/*.out; show_logs; skip "a Slurm daemon exited (pid $p)"; }; done
  sleep 0.25
done
[ "$state" = "idle" ] || { show_logs; skip "the node did not become idle in 15 s (state '$state')"; }
echo "slurm: node $host idle after $SECONDS s"

# A 2-entry manifest through the sample script.
cat > "$WORK/manifest.json" << JSON
{"defaults": {"frames": 8, "outputs": ["pc2", "mdd"]},
 "jobs": [{"name": "strip", "mesh": "$MESH_DIR/strip_8x4.obj", "pins": {"top_axis": "y"}},
          {"name": "patch", "mesh": "$MESH_DIR/tri_patch.obj", "pins": {"top_axis": "y"}}]}
JSON
RBCLOTH=$RBCLOTH timeout 20 "$SAMPLES/submit.sh" "$WORK/manifest.json" "$WORK/out" || fail "submit.sh failed"
report=$WORK/out/batch_report.json
for _ in $(seq 240); do
  [ -f "$report" ] && [ -z "$(timeout 3 squeue -h -o %i 2> /dev/null)" ] && break
  sleep 0.25
done
[ -f "$report" ] || fail "no merged report after 60 s: $(timeout 3 squeue 2>&1)"
echo "slurm: merged report after $SECONDS s"
grep -Eq '"merged":[[:space:]]*true' "$report" || fail "report not from --report-only"
grep -Eq '"jobs_ok":[[:space:]]*2' "$report" || { cat "$report"; fail "not 2 jobs ok"; }
for j in strip patch; do
  [ -f "$WORK/out/$j/$j.result.json" ] || fail "no $j.result.json"
  [ -f "$WORK/out/$j/$j.pc2" ] || fail "no $j.pc2"
  grep -q "| $j | ok |" "$WORK/out/batch_report.md" || fail "$j not ok in batch_report.md"
done
ls "$WORK"/out/slurm-*_0.log "$WORK"/out/slurm-*_1.log "$WORK"/out/slurm-*-merge.log > /dev/null ||
  fail "missing Slurm logs of the 2 array tasks and the merge"
echo "PASS: 2 array tasks and the merge step on a one-node Slurm in $SECONDS s"
