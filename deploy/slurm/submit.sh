#!/bin/bash
# Renders SCENE on a Slurm cluster in N bands, one array task each (render-tile.sbatch), then
# merges them into OUT/image.exr and OUT/image.png once every band has finished (a job that
# depends on the whole array).
#
#   deploy/slurm/submit.sh SCENE.toml OUT N [strahl render flags...]
#   deploy/slurm/submit.sh assets/scenes/seed.toml /shared/seed 8 --mode path --spp 256
#
# The logs go to OUT. Extra flags (--mode, --spp, --width, --backend, ...) apply to every band.
# Extra sbatch options (partition, account, time limit) come from the environment as usual:
# SBATCH_PARTITION, SBATCH_ACCOUNT, SBATCH_TIMELIMIT.
set -euo pipefail

if (($# < 3)); then
    echo "usage: $0 SCENE.toml OUT N [strahl render flags...]" >&2
    exit 2
fi
scene=$1
out=$2
n=$3
shift 3
if ! [[ $n =~ ^[1-9][0-9]*$ ]]; then
    echo "$0: N must be a whole number of bands, at least 1, not '$n'" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
array=$(sbatch --parsable --array="0-$((n - 1))" --output="$out/tile-%a.log" \
    "$here/render-tile.sbatch" "$scene" "$out" "$n" "$@")
array=${array%%;*} # --parsable prints JOBID[;CLUSTER]
parts=$(printf '%q/part-*.exr' "$out")
merge="strahl merge $parts -o $(printf '%q' "$out/image.exr") && strahl merge $parts -o $(printf '%q' "$out/image.png")"
merged=$(sbatch --parsable --job-name=strahl-merge --dependency="afterok:$array" \
    --output="$out/merge.log" --wrap "$merge")
echo "submitted: bands $array (array of $n), merge ${merged%%;*} after them; the image will be $out/image.exr"
