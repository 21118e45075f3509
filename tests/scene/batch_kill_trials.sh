#!/usr/bin/env bash
# batch_kill_trials.sh RBCLOTH MESH_DIR WORK [TRIALS] [SEED]
#
# Kill-and-resume trials of `rbcloth batch` (issue 17): one uninterrupted reference
# batch, then per trial a batch stopped at a random time -- SIGKILL of the parent
# alone (half the trials), SIGKILL of a random worker and then of the parent (a
# quarter), or SIGTERM to the parent (a quarter) -- and resumed at once, again and
# again until a resume exits 0; a resume is itself SIGKILLed at a random time one
# time in three (at most twice a trial). Then every output of every job (results
# and status files aside: they hold timings) is compared byte for byte with the
# reference, and nothing of the trial may be left: no process of its batches, no
# temporary file. The solver is deterministic for a fixed thread count (each job
# runs on 1 thread).
#
# Prints one line, "trials N, kills K, resumes R, outputs compared C, mismatches M,
# stray processes S, temporaries left T", and exits 1 unless M, S and T are 0.
# TRIALS defaults to 20, SEED (bash's $RANDOM) to the time.
set -u
cli=$1 work=$3 trials=${4:-20} seed=${5:-$(date +%s)}
meshes=$(cd "$2" && pwd) || exit 2 # the manifest's paths resolve against its folder
RANDOM=$seed
rm -rf "$work" && mkdir -p "$work" || exit 2
manifest=$work/manifest.json
cat > "$manifest" << JSON
{"defaults": {"outputs": ["pc2", "mdd", "objseq"]},
 "jobs": [
  {"name": "strip", "mesh": "$meshes/strip_8x4.obj", "frames": 30},
  {"name": "grid", "mesh": "$meshes/grid_20x20.obj", "frames": 400, "pins": {"top_axis": "z"},
   "outputs": ["pc2", "mdd"]},
  {"name": "scene", "scene": "default", "frames": 40, "outputs": ["pc2", "mdd"]},
  {"name": "patch", "mesh": "$meshes/tri_patch.obj", "frames": 300, "pins": {"top_axis": "y"}}
 ]}
JSON
jobs=(strip grid scene patch)

now_ms() { date +%s%3N; }
# The children of pid $1 that run (not zombies).
children() {
  awk -v parent="$1" '{ s = $0; sub(/^.*\) /, "", s); split(s, f, " ") # state ppid ...
    if (f[2] == parent && f[1] != "Z") { p = FILENAME; gsub(/[^0-9]/, "", p); print p } }' \
    /proc/[0-9]*/stat 2> /dev/null
}
# Processes of a trial's batches (parents and workers, which share the command
# line): those whose last argument, --out's, is folder $1; zombies left out.
strays() {
  local f st
  for f in $(grep -lzxF -- "$1" /proc/[0-9]*/cmdline 2> /dev/null); do
    st=$(cat "${f%cmdline}stat" 2> /dev/null) || continue
    st=${st##*) }
    [ "${st:0:1}" = Z ] || { f=${f#/proc/}; echo "${f%/cmdline}"; }
  done
}
# A random number of milliseconds in [50, $1).
random_ms() { echo $((50 + (RANDOM * 32768 + RANDOM) % ($1 - 50))); }
sleep_ms() { sleep "$(printf '%d.%03d' $(($1 / 1000)) $(($1 % 1000)))"; }
batch=("$cli" batch "$manifest" -j 2 --quiet --out)

t0=$(now_ms)
if ! "${batch[@]}" "$work/reference" > "$work/reference.log" 2>&1; then
  cat "$work/reference.log"
  exit 2
fi
ref_ms=$(($(now_ms) - t0))
[ "$ref_ms" -gt 200 ] || ref_ms=200
echo "reference batch: $ref_ms ms; seed $seed"

kills=0 resumes=0 compared=0 mismatches=0 stray=0 temporaries=0
for trial in $(seq "$trials"); do
  out=$work/trial_$trial log=$work/trial_$trial.log
  mode=$((RANDOM % 4)) # 0, 1: parent; 2: a worker, then the parent; 3: SIGTERM
  "${batch[@]}" "$out" > "$log" 2>&1 & # $!: rbcloth itself, not a subshell
  pid=$!
  sleep_ms "$(random_ms $((ref_ms * 7 / 10)))"
  if kill -0 "$pid" 2> /dev/null; then
    case $mode in
      2) workers=($(children "$pid"))
         if [ ${#workers[@]} -gt 0 ]; then
           kill -KILL "${workers[RANDOM % ${#workers[@]}]}" 2> /dev/null && kills=$((kills + 1))
           sleep_ms $((RANDOM % 100))
         fi
         kill -KILL "$pid" 2> /dev/null && kills=$((kills + 1)) ;;
      3) kill -TERM "$pid" 2> /dev/null && kills=$((kills + 1)) ;;
      *) kill -KILL "$pid" 2> /dev/null && kills=$((kills + 1)) ;;
    esac
  fi
  wait "$pid" 2> /dev/null
  # Resume at once, until one run finishes every job.
  killed_resumes=0
  while :; do
    resumes=$((resumes + 1))
    echo "--- resume $resumes" >> "$log"
    if [ $killed_resumes -lt 2 ] && [ $((RANDOM % 3)) -eq 0 ]; then
      killed_resumes=$((killed_resumes + 1))
      "${batch[@]}" "$out" >> "$log" 2>&1 &
      pid=$!
      sleep_ms "$(random_ms $((ref_ms * 7 / 10)))"
      kill -KILL "$pid" 2> /dev/null && kills=$((kills + 1))
      wait "$pid" 2> /dev/null && break # (it may have ended before the kill)
      continue
    fi
    "${batch[@]}" "$out" >> "$log" 2>&1
    done_rc=$?
    # A batch that ended by itself held the folder alone: no process of an earlier
    # one can be left.
    left=$(strays "$out")
    if [ -n "$left" ]; then
      echo "trial $trial: processes still running after a resume: $left"
      stray=$((stray + $(echo "$left" | wc -l)))
      kill -KILL $left 2> /dev/null
    fi
    [ $done_rc -eq 0 ] && break
    if [ $resumes -gt $((trials * 10)) ]; then
      echo "trial $trial: no resume succeeded"; tail -20 "$log"; exit 1
    fi
  done
  # No temporary file is left, and every output is the reference's.
  tmp=$(find "$out" -name '*.tmp*' | wc -l)
  [ "$tmp" -eq 0 ] || { echo "trial $trial: temporary files left:"; find "$out" -name '*.tmp*'; }
  temporaries=$((temporaries + tmp))
  for j in "${jobs[@]}"; do
    # Every file of the reference's job folder, and none more, with the same bytes.
    n=$(find "$work/reference/$j" -type f ! -name '*.result.json' ! -name '*.status.json' | wc -l)
    compared=$((compared + n))
    diffs=$(diff -rq -x '*.result.json' -x '*.status.json' "$work/reference/$j" "$out/$j" 2>&1)
    if [ -n "$diffs" ]; then
      echo "trial $trial (mode $mode): $j differs from the reference:"
      echo "$diffs" | head -5
      mismatches=$((mismatches + $(echo "$diffs" | wc -l)))
    fi
  done
  rm -rf "$out" # the next trial's disk
done
echo "trials $trials, kills $kills, resumes $resumes, outputs compared $compared," \
  "mismatches $mismatches, stray processes $stray, temporaries left $temporaries"
[ "$mismatches" -eq 0 ] && [ "$stray" -eq 0 ] && [ "$temporaries" -eq 0 ]
