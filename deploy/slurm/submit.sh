#!/bin/bash
# Renders SCENE on a Slurm cluster in N bands, one array task each (render-tile.sbatch), then
# merges them into OUT/image.exr and OUT/image.png once every band has ended (a job that
# depends on the whole array).
#
#   deploy/slurm/submit.sh [-c CPUS] [--bands LIST] SCENE.toml OUT N [strahl render flags...]
#   deploy/slurm/submit.sh assets/scenes/seed.toml /shared/seed 8 --mode path --spp 256
#   deploy/slurm/submit.sh -c 8 assets/scenes/seed.toml /shared/seed 8 --mode path --spp 256
#
# -c CPUS, --cpus-per-task=CPUS   CPUs for each band (default 1, which every node has).
# --bands LIST                    render only these bands, in Slurm's array syntax (3, 1,5 or
#                                 2-4), then merge again: for bands that failed or were
#                                 cancelled. The same SCENE, N and flags give the same image
#                                 bit for bit.
#
# Extra flags (--mode, --spp, --width, --backend, ...) apply to every band. Other sbatch options
# (partition, account, time limit, memory) come from the environment as usual: SBATCH_PARTITION,
# SBATCH_ACCOUNT, SBATCH_TIMELIMIT, SBATCH_MEM_PER_NODE.
#
# Before submitting, the request is tried with `sbatch --test-only`: one that no node of the
# cluster can satisfy is refused here, naming the resource, instead of pending forever. The
# logs go to OUT, the job ids to OUT/jobs; deploy/slurm/status.sh OUT says which bands are
# done, running or missing.
set -euo pipefail

me=$0
usage() {
    echo "usage: $me [-c CPUS] [--bands LIST] SCENE.toml OUT N [strahl render flags...]" >&2
    exit 2
}
fail() {
    echo "$me: $*" >&2
    exit 1
}

cpus=1
bands=
while (($#)); do
    case $1 in
    -c | --cpus-per-task) (($# >= 2)) || usage; cpus=$2; shift 2 ;;
    -c* ) cpus=${1#-c}; shift ;;
    --cpus-per-task=*) cpus=${1#*=}; shift ;;
    --bands) (($# >= 2)) || usage; bands=$2; shift 2 ;;
    --bands=*) bands=${1#*=}; shift ;;
    --) shift; break ;;
    -*) echo "$me: unknown option $1 (options come before SCENE)" >&2; usage ;;
    *) break ;;
    esac
done
(($# >= 3)) || usage
scene=$1
out=$2
n=$3
shift 3
if ! [[ $n =~ ^[1-9][0-9]*$ ]]; then
    echo "$me: N must be a whole number of bands, at least 1, not '$n'" >&2
    exit 2
fi
if ! [[ $cpus =~ ^[1-9][0-9]*$ ]]; then
    echo "$me: -c: CPUs per band must be a whole number, at least 1, not '$cpus'" >&2
    exit 2
fi
if [[ -z $bands ]]; then
    bands="0-$((n - 1))"
elif ! [[ $bands =~ ^[0-9]+(-[0-9]+)?(,[0-9]+(-[0-9]+)?)*$ ]]; then
    echo "$me: --bands: a list of bands such as 3, 1,5 or 2-4, not '$bands'" >&2
    exit 2
else
    for b in ${bands//[,-]/ }; do
        ((10#$b < n)) || { echo "$me: --bands: band $b does not exist; the bands are 0 to $((n - 1))" >&2; exit 2; }
    done
fi
command -v sbatch >/dev/null 2>&1 || fail "sbatch not found: run this on a Slurm login node"

here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
array_opts=(--array="$bands" --cpus-per-task="$cpus" --output="$out/tile-%a.log")
task=("$here/render-tile.sbatch" "$scene" "$out" "$n" "$@")

# The largest value of sinfo's field FORMAT over the nodes of the partition the job goes to.
most() {
    sinfo -h -N ${SBATCH_PARTITION:+-p "$SBATCH_PARTITION"} -o "$1" 2>/dev/null | tr -d '+' | sort -n | tail -1
}
# A request no node can satisfy is accepted by sbatch and then pends for ever (reason
# PartitionConfig); --test-only refuses it at once.
if ! tried=$(sbatch --test-only "${array_opts[@]}" "${task[@]}" 2>&1); then
    where=${SBATCH_PARTITION:+partition $SBATCH_PARTITION}
    where=${where:-any partition}
    max_cpus=$(most %c)
    if [[ $max_cpus =~ ^[0-9]+$ ]] && ((cpus > max_cpus)); then
        fail "no node in $where has $cpus CPUs for a band (-c $cpus); the most a node has is $max_cpus: ask for at most -c $max_cpus"
    fi
    max_mem=$(most %m)
    if [[ ${SBATCH_MEM_PER_NODE:-} =~ ^([0-9]+)([KMGT]?)$ && $max_mem =~ ^[0-9]+$ ]]; then
        mem=${BASH_REMATCH[1]}
        case ${BASH_REMATCH[2]} in K) mem=$((mem / 1024)) ;; G) mem=$((mem * 1024)) ;; T) mem=$((mem * 1024 * 1024)) ;; esac
        if ((mem > max_mem)); then
            fail "no node in $where has ${SBATCH_MEM_PER_NODE} of memory (SBATCH_MEM_PER_NODE); the most a node has is ${max_mem}M"
        fi
    fi
    fail "the cluster cannot run this request; sbatch --test-only says: $(tr '\n' ' ' <<<"$tried")"
fi

array=$(sbatch --parsable "${array_opts[@]}" "${task[@]}")
array=${array%%;*} # --parsable prints JOBID[;CLUSTER]
parts=$(printf '%q/part-*.exr' "$out")
merge="strahl merge $parts -o $(printf '%q' "$out/image.exr") && strahl merge $parts -o $(printf '%q' "$out/image.png")"
# afterany, not afterok: the merge runs however the bands ended, and where one is missing it
# names it in merge.log, where afterok would leave the merge pending for ever.
merged=$(sbatch --parsable --job-name=strahl-merge --dependency="afterany:$array" \
    --output="$out/merge.log" --wrap "$merge")
merged=${merged%%;*}
{
    printf 'bands %s %s %s\n' "$array" "$n" "$bands"
    printf 'merge %s\n' "$merged"
    printf 'command'
    printf ' %q' "$me" -c "$cpus" --bands BANDS "$scene" "$out" "$n" "$@"
    printf '\n'
} >>"$out/jobs"
echo "submitted: bands $bands of $n as job array $array ($cpus CPU(s) each), merge $merged after them; the image will be $out/image.exr"
echo "progress: $here/status.sh $(printf '%q' "$out")"
