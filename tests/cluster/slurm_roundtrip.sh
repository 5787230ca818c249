#!/usr/bin/env bash
# The Slurm recipe of docs/cluster.md on a real scheduler: brings up a private single-node Slurm (Debian's
# slurm-wlm and munge, its own slurm.conf and munge key in a temporary folder, daemons on free ports), runs
# `lodforge run --shard K/N` as an array job over the batch tests' generated library with every shard writing
# into one folder, merges the shard reports with `lodforge merge-reports`, and compares with an unsharded run:
# every output file and lods.json byte for byte, the merged report.json but for what legitimately differs
# (cluster_test_tool same-report says what), the cache keys. Stops every daemon it started, also on failure.
#   tests/cluster/slurm_roundtrip.sh LODFORGE CLUSTER_TEST_TOOL      (ctest runs it as SlurmRoundTrip)
# Exit 0 passed, 1 failed, 77 skipped with a message: not root, the packages absent (scripts/setup.sh installs
# them where it can), or the daemons do not come up in this container.
#   SHARDS   array size (default 3)          ASSETS  library size (default 60)
#   KEEP     1: keep the temporary folder (slurm.conf, daemon and task logs, outputs) and print its path
set -euo pipefail

SKIP=77
if [ $# -ne 2 ]; then
  echo "usage: $0 LODFORGE CLUSTER_TEST_TOOL" >&2
  exit 2
fi
lodforge=$(realpath "$1")
tool=$(realpath "$2")
shards=${SHARDS:-3}
assets=${ASSETS:-60}
started=$SECONDS

skip() {
  echo "SKIP: $*"
  exit "$SKIP"
}
fail() {
  echo "FAIL: $*"
  exit 1
}

# The daemons live in sbin, which a non-root PATH may lack.
export PATH="$PATH:/usr/sbin:/sbin"
for c in munged slurmctld slurmd sbatch sinfo scancel; do
  command -v "$c" >/dev/null 2>&1 ||
    skip "'$c' not found: install Debian's slurm-wlm and munge (scripts/setup.sh tries to) to run the Slurm round trip"
done
# slurmd starts each job as its owner, which needs root.
[ "$(id -u)" -eq 0 ] || skip "the private Slurm needs root (slurmd starts jobs as their owner)"
# Only this cluster: no settings of a surrounding Slurm job or installation may leak into the clients.
for v in $(compgen -e | grep '^SLURM_' || true); do unset "$v"; done

work=$(mktemp -d "${TMPDIR:-/tmp}/lodforge-slurm.XXXXXX")
chmod 755 "$work"  # munged wants its socket's folder searchable by everyone
mkdir -p "$work/state" "$work/spool" "$work/logs"
export SLURM_CONF="$work/slurm.conf"
daemons=()  # pids of the daemons this script started, in start order
sbatch_pid=""

show_logs() {
  local f
  for f in "$work"/munged.log "$work"/slurmctld.log "$work"/slurmd.log "$work"/logs/*; do
    [ -s "$f" ] || continue
    echo "---- last lines of $f"
    tail -n 15 "$f"
  done
}

cleanup() {
  local rc=$? pid i
  trap - EXIT INT TERM
  [ -z "$sbatch_pid" ] || kill -TERM "$sbatch_pid" 2>/dev/null || true
  if [ ${#daemons[@]} -gt 1 ]; then
    scancel --quiet --user="$(id -un)" >/dev/null 2>&1 || true  # a job left by a failure or a time-out
  fi
  # The daemons in reverse order (slurmd, slurmctld, munged), each by the pid this script started it with.
  for ((i = ${#daemons[@]} - 1; i >= 0; i--)); do
    pid=${daemons[i]}
    kill -TERM "$pid" 2>/dev/null || continue
    for _ in $(seq 50); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  [ "$rc" -eq 0 ] || [ "$rc" -eq "$SKIP" ] || show_logs
  if [ "${KEEP:-0}" = 1 ]; then
    echo "kept $work"
  else
    rm -rf "$work"
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# A TCP port on 127.0.0.1 that nothing listens on (not one of `taken`).
free_port() {
  local p
  for _ in $(seq 100); do
    p=$((20000 + RANDOM % 30000))
    [[ " $* " == *" $p "* ]] && continue
    (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null || {
      echo "$p"
      return 0
    }
  done
  return 1
}

# ---- munge: its own key and socket ----
if command -v mungekey >/dev/null 2>&1; then
  mungekey --create --keyfile="$work/munge.key"
else
  dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
fi
chmod 600 "$work/munge.key"
munged --foreground --key-file="$work/munge.key" --socket="$work/munge.sock" --pid-file="$work/munged.pid" \
  --seed-file="$work/munged.seed" >"$work/munged.log" 2>&1 &
daemons+=($!)
for _ in $(seq 100); do
  [ -S "$work/munge.sock" ] && break
  kill -0 "${daemons[0]}" 2>/dev/null || break
  sleep 0.1
done
if [ ! -S "$work/munge.sock" ]; then
  tail -n 5 "$work/munged.log"
  skip "munged did not start in this container (log above)"
fi

# ---- Slurm: one node with this machine's cores, one partition, no accounting, no cgroups ----
ctld_port=$(free_port) || skip "no free TCP port for slurmctld"
slurmd_port=$(free_port "$ctld_port") || skip "no free TCP port for slurmd"
host=$(hostname -s)
user=$(id -un)
cat >"$SLURM_CONF" <<EOF
ClusterName=lodforge-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge.sock
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
# No cgroups (a container may not delegate them): processes tracked by parentage, tasks not confined.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/builtin
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
# The node is what this file says, whatever the hardware probe finds.
SlurmdParameters=config_overrides
# sbatch --wait polls every 2 s only while that is under MinJobAge/2 (else every 8 s, then 32 s); a finished
# job's record outlives the next poll at 4 s.
MinJobAge=4
NodeName=lodforge-node NodeHostname=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=lodforge Nodes=ALL Default=YES MaxTime=10 State=UP
EOF
slurmctld -D -f "$SLURM_CONF" >"$work/slurmctld.out" 2>&1 &
daemons+=($!)
slurmd -D -f "$SLURM_CONF" -N lodforge-node >"$work/slurmd.out" 2>&1 &
daemons+=($!)
state=""
for _ in $(seq 150); do
  state=$(sinfo --noheader --Node --format=%t 2>/dev/null || true)
  [ "$state" = idle ] && break
  if ! kill -0 "${daemons[1]}" 2>/dev/null || ! kill -0 "${daemons[2]}" 2>/dev/null; then break; fi  # one exited
  sleep 0.2
done
if [ "$state" != idle ]; then
  show_logs
  tail -n 5 "$work/slurmctld.out" "$work/slurmd.out" 2>/dev/null || true
  skip "the single-node Slurm did not come up in this container (node state '${state:-none}'; logs above)"
fi
echo "slurm: node idle after $((SECONDS - started)) s (ports $ctld_port, $slurmd_port, $(nproc) CPUs)"

# ---- the library, and the unsharded run to compare with ----
library=$("$tool" write-library "$work" "$assets")
echo "$library"
files=${library%% *}  # "62 assets in ...": the fixture adds two copies of one mesh to the count asked for
config="$work/batch_config.json"
"$lodforge" run --config "$config" --input "$work/lib" --output "$work/whole" >"$work/logs/whole.log" 2>&1 ||
  fail "the unsharded run exited $? (log: $(tail -n 3 "$work/logs/whole.log"))"

# ---- the array job: docs/cluster.md's lodforge.sbatch, shrunk to this node ----
cat >"$work/lodforge.sbatch" <<EOF
#!/bin/bash
#SBATCH --job-name=lodforge
#SBATCH --cpus-per-task=1
#SBATCH --time=5
#SBATCH --signal=B:TERM@30
#SBATCH --output=$work/logs/lodforge-%A_%a.log
set -euo pipefail
exec "$lodforge" run \\
  --config "$config" \\
  --input "$work/lib" \\
  --output "$work/sharded" \\
  --jobs "\$SLURM_CPUS_PER_TASK" \\
  --shard "\$SLURM_ARRAY_TASK_ID/\$SLURM_ARRAY_TASK_COUNT"
EOF
submitted=$SECONDS
# --wait: exit status = the highest of the tasks'. In the background so that a signal reaches the trap now.
timeout 240 sbatch --wait --quiet --chdir="$work" --array="0-$((shards - 1))" "$work/lodforge.sbatch" &
sbatch_pid=$!
rc=0
wait "$sbatch_pid" || rc=$?
sbatch_pid=""
[ "$rc" -eq 0 ] || fail "the array job exited $rc (124: still running after 240 s)"
echo "slurm: array job of $shards shards done in $((SECONDS - submitted)) s"
shopt -s nullglob
task_logs=("$work"/logs/lodforge-*_*.log)
shopt -u nullglob
[ ${#task_logs[@]} -eq "$shards" ] || fail "expected $shards task logs, found ${#task_logs[@]}"
reports=()
for ((k = 0; k < shards; k++)); do
  r="$work/sharded/report.shard-$k-of-$shards.json"
  [ -f "$r" ] || fail "shard $k wrote no $r"
  reports+=("$r")
done
[ ! -e "$work/sharded/report.json" ] || fail "a shard wrote report.json"
"$lodforge" merge-reports "$work/sharded/report.json" "${reports[@]}"

# ---- the comparison ----
# Every file of the two output folders but the cache (compared by key below) and the reports (report.json
# below; report.html renders the timings; the shard reports and shard manifests exist only in the sharded run):
# the same names, the same bytes. lods.json, written by merge-reports in the sharded run, is among them.
outputs() {
  (cd "$1" && find . -type f | sed 's|^\./||' |
    grep -Ev '^(\.lodforge-cache/|report\.json$|report\.html$|report\.shard-|lods\.shard-)' | LC_ALL=C sort)
}
if ! diff <(outputs "$work/whole") <(outputs "$work/sharded") >"$work/names.diff"; then
  head -n 20 "$work/names.diff"
  fail "the sharded run wrote other files than the unsharded one (< unsharded, > sharded)"
fi
count=0
while IFS= read -r f; do
  cmp -s "$work/whole/$f" "$work/sharded/$f" || fail "$f differs between the unsharded and the sharded run"
  count=$((count + 1))
done < <(outputs "$work/whole")
[ "$count" -gt "$files" ] || fail "only $count output files for $files assets"
[ -f "$work/sharded/lods.json" ] || fail "merge-reports wrote no lods.json"
[ -f "$work/sharded/report.html" ] || fail "merge-reports wrote no report.html"
"$tool" same-report "$work/whole/report.json" "$work/sharded/report.json" ||
  fail "the merged report differs from the unsharded run's"
# Cache keys depend on content, config and version, never on the shard: the same entries.
entries() { find "$1/.lodforge-cache/entries" -type f -printf '%f\n' | LC_ALL=C sort; }
[ "$(entries "$work/whole" | wc -l)" -ge "$files" ] || fail "fewer cache entries than assets in the unsharded run"
diff <(entries "$work/whole") <(entries "$work/sharded") >/dev/null || fail "the cache entries differ"
# Nothing left half-written: temporary files of atomic writes or staged outputs.
leftovers=$(cd "$work/sharded" && find . -type f \( -name '*.tmp-*' -o -path '*/staging-*' \) | head -n 5)
[ -z "$leftovers" ] || fail "leftovers in the shared output folder: $leftovers"

echo "PASS: $shards Slurm array tasks over $files assets: $count output files, lods.json and the merged" \
  "report equal the unsharded run's ($((SECONDS - started)) s in all)"
