#!/usr/bin/env bash
# `umbra farm submit` on a real Slurm cluster of one node, started here
# (docs/farm.md, "The test"). As root: munged (as the munge user, its own
# key, socket, pid and log), slurmctld and slurmd with a generated
# slurm.conf in a temporary directory, ports chosen from this shell's pid.
# A five-frame animation whose frames share one depth map is submitted;
# every frame must be byte-identical to the frame rendered locally (both
# with SOURCE_DATE_EPOCH), the array tasks must read the map from the map
# cache, and the report must list every frame. The daemons are stopped by
# their pid files on every exit; on failure their logs are printed.
#
# Usage: slurm_test.sh /path/to/umbra
# A cluster that cannot be started (not root, among other reasons) is a
# failure that says why, never a skip or a pass (issue 19).
set -uo pipefail

umbra=${1:?usage: slurm_test.sh /path/to/umbra}
umbra=$(readlink -f "$umbra")

if [ "$(id -u)" -ne 0 ]; then
  echo "FAIL: starting slurmctld, slurmd and munged needs root (this is uid $(id -u)); run the suite as root" >&2
  exit 1
fi

fail() {
  echo "FAIL: $*" >&2
  exit 1
}

for tool in munged slurmctld slurmd sbatch sinfo scancel; do
  command -v "$tool" >/dev/null ||
    fail "$tool is not installed: Slurm cannot be started (apt-get install slurm-wlm munge; scripts/install-deps.sh does)"
done
id munge >/dev/null 2>&1 || fail "there is no munge user (the munge package makes it)"

work=$(mktemp -d /tmp/umbra-slurm.XXXXXX)
chmod 755 "$work"
ok=0

stop_daemons() {
  # The jobs first (their steps are slurmd's children), then the daemons,
  # each by its pid file.
  if [ -e "$work/slurmctld.pid" ]; then
    scancel --quiet --user=root >/dev/null 2>&1 || true
  fi
  for pidfile in "$work/slurmd.pid" "$work/slurmctld.pid" "$work/munge/munged.pid"; do
    [ -s "$pidfile" ] || continue
    pid=$(cat "$pidfile")
    kill "$pid" 2>/dev/null || continue
    for _ in $(seq 50); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
    kill -9 "$pid" 2>/dev/null || true
  done
}

on_exit() {
  stop_daemons
  if [ "$ok" != 1 ]; then
    for log in "$work/munge/munged.log" "$work/slurmctld.log" "$work/slurmd.log" "$work"/farm/logs/*.log \
               "$work/submit.log" "$work/local.log"; do
      [ -e "$log" ] || continue
      echo "==== $log" >&2
      tail -n 60 "$log" >&2
    done
  fi
  rm -rf "$work"
}
trap on_exit EXIT
trap 'exit 1' INT TERM

# munged, as the munge user, with its own key, socket, pid, seed and log.
mkdir -p "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chown -R munge: "$work/munge"
chmod 700 "$work/munge"
chmod 600 "$work/munge/munge.key"
socket="$work/munge/munge.socket"
runuser -u munge -- munged --force -S "$socket" --key-file="$work/munge/munge.key" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" --seed-file="$work/munge/munged.seed" ||
  fail "munged did not start (see its log below)"
# root reaches the socket through the munge-owned directory.
chmod 755 "$work/munge"
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
[ -S "$socket" ] || fail "munged made no socket at $socket"

# slurm.conf: ports from this shell's pid, so concurrent runs do not clash.
ctld_port=$((20000 + ($$ % 20000) * 2))
slurmd_port=$((ctld_port + 1))
node=$(hostname -s)
mkdir -p "$work/state" "$work/spool"
export SLURM_CONF="$work/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=umbratest
SlurmctldHost=localhost
SlurmUser=root
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
SchedulerType=sched/builtin
SchedulerParameters=sched_interval=1
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MailProg=/bin/true
NodeName=$node NodeHostname=$(hostname) NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=umbra Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

slurmctld -c -f "$SLURM_CONF" || fail "slurmctld did not start (see its log below)"
slurmd -f "$SLURM_CONF" -N "$node" || fail "slurmd did not start (see its log below)"
state=""
for _ in $(seq 150); do
  state=$(sinfo -h -N -n "$node" -o %t 2>/dev/null | head -n1)
  [ "$state" = idle ] && break
  sleep 0.2
done
[ "$state" = idle ] || fail "the node $node did not become idle within 30 s (last state: '${state:-none}')"

# Five frames, the camera moving, the spotlight and its casters still: one
# depth map for the whole shot.
scene="$work/shot.rib"
{
  echo 'Format 64 48 1'
  echo 'PixelSamples 2 2'
  for n in 1 2 3 4 5; do
    cat <<EOF
FrameBegin $n
Display "out.####.tif" "file" "rgba"
Projection "perspective" "fov" 40
Translate 0.$n 0 5
WorldBegin
  LightSource "shadowspot" "key" "from" [0.5 4 0.3] "to" [0 0 0] "coneangle" [0.9] "intensity" [16] "shadowname" ["auto"]
  Surface "matte"
  AttributeBegin
    Translate 0 0.5 0
    Sphere 0.6 -0.6 0.6 360
  AttributeEnd
  Patch "bilinear" "P" [-3 -0.5 -3  3 -0.5 -3  -3 -0.5 3  3 -0.5 3]
WorldEnd
FrameEnd
EOF
  done
} >"$scene"

export SOURCE_DATE_EPOCH=1700000000
mkdir -p "$work/local" "$work/images"
(cd "$work/local" && "$umbra" render --threads 1 "$scene" >"$work/local.log" 2>&1) ||
  fail "the local render failed"

(cd "$work/images" && "$umbra" farm submit --chunk 2 "$scene" -o "$work/farm" >"$work/submit.log" 2>&1) ||
  fail "umbra farm submit failed: $(cat "$work/submit.log")"
cat "$work/submit.log"

# Wait (at most 400 s) for the report job's last output; it runs last.
for _ in $(seq 2000); do
  [ -e "$work/farm/report/failed.txt" ] && break
  sleep 0.2
done
[ -e "$work/farm/report/failed.txt" ] || fail "the report job did not finish within 400 s"

for n in 1 2 3 4 5; do
  image=$(printf 'out.%04d.tif' "$n")
  [ -e "$work/images/$image" ] || fail "frame $n: the farm wrote no $image"
  cmp "$work/local/$image" "$work/images/$image" || fail "frame $n: the farm's $image differs from the local one"
done
[ -s "$work/farm/report/missing.txt" ] && fail "the report names jobs without statistics: $(cat "$work/farm/report/missing.txt")"
[ -s "$work/farm/report/failed.txt" ] && fail "the report names failed jobs: $(cat "$work/farm/report/failed.txt")"
grep -q '"reused":false' "$work/farm/stats/maps.jsonl" || fail "the maps job did not render its map"
for task in 0 1; do
  first=$(head -n1 "$work/farm/stats/task.$task.jsonl")
  grep -q '"reason":"map cache"' <<<"$first" || fail "array task $task did not read the map from the cache: $first"
done
for n in 1 2 3 4 5; do
  grep -Eq "^\| $n \|" "$work/farm/report/report.md" || fail "the report lists no frame $n"
done
[ -s "$work/farm/report/report.html" ] || fail "the report has no report.html"

ok=1
echo "PASS: five frames rendered on Slurm, identical to the local render"
