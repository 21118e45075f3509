#!/usr/bin/env bash
# submit.sh SOURCE OUT [rbcloth batch options]: run `rbcloth batch SOURCE` on Slurm,
# one array task per manifest entry (or per mesh of a folder, with --template),
# then a merge step once every task has ended, whatever its outcome.
# Extra sbatch options (partition, time, account) go in SBATCH_ARGS.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: submit.sh MANIFEST.json|MESHDIR OUT [--template T.json] [...]" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
RBCLOTH=${RBCLOTH:-rbcloth}
export RBCLOTH
src=$(realpath "$1")
mkdir -p "$2"
out=$(realpath "$2")
shift 2
n=$("$RBCLOTH" batch "$src" --count "$@")
# shellcheck disable=SC2086  # SBATCH_ARGS is a list of options
array=$(sbatch --parsable ${SBATCH_ARGS:-} --array="0-$((n - 1))" \
  --output="$out/slurm-%A_%a.log" "$here/rbcloth_batch.sbatch" "$src" "$out" "$@")
array=${array%%;*}
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --dependency="afterany:$array" \
  --job-name=rbcloth-merge --output="$out/slurm-%j-merge.log" \
  "$here/rbcloth_batch.sbatch" "$src" "$out" "$@")
merge=${merge%%;*}
echo "rbcloth: array job $array ($n tasks), merge job $merge; report: $out/batch_report.md"
