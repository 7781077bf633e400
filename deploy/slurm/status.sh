#!/bin/bash
# Says which bands of a split render submitted by deploy/slurm/submit.sh are done, running,
# pending or missing, and whether the merge has run:
#
#   deploy/slurm/status.sh OUT
#
# A band is done when OUT/part-K.exr exists (strahl writes it whole or not at all), running or
# pending while a task of one of OUT/jobs' arrays is, and missing otherwise (it failed, was
# cancelled or killed): the line says how to render it again. Exits 0 when the merged image is
# there, 1 while anything is missing or not yet done.
set -euo pipefail

if (($# != 1)); then
    echo "usage: $0 OUT" >&2
    exit 2
fi
out=$1
jobs=$out/jobs
[[ -f $jobs ]] || { echo "$0: $jobs not found: was OUT submitted with deploy/slurm/submit.sh?" >&2; exit 2; }

n=$(awk '$1 == "bands" { n = $3 } END { print n }' "$jobs")
arrays=$(awk '$1 == "bands" { printf "%s%s", sep, $2; sep = "," }' "$jobs")
merges=$(awk '$1 == "merge" { printf "%s%s", sep, $2; sep = "," }' "$jobs")
command=$(awk '$1 == "command" { sub(/^command /, ""); c = $0 } END { print c }' "$jobs")

# Array tasks as "JOBID_K STATE": squeue -r lists each task of an array on its own line.
queued=$(squeue -h -r -j "$arrays,$merges" -o '%i %T' 2>/dev/null || true)

missing=()
unfinished=0
for ((k = 0; k < n; k++)); do
    if [[ -f $out/part-$k.exr ]]; then
        echo "band $k of $n: done ($out/part-$k.exr)"
        continue
    fi
    unfinished=1
    state=$(awk -v k="$k" -v ids=",$arrays," '
        { split($1, id, "_") }
        index(ids, "," id[1] ",") && id[2] != "" && id[2] + 0 == k { print tolower($2) " (job " $1 ")"; exit }' <<<"$queued")
    if [[ -n $state ]]; then
        echo "band $k of $n: $state"
    else
        echo "band $k of $n: missing (not queued, no part; see $out/tile-$k.log)"
        missing+=("$k")
    fi
done

merge_state=$(awk -v ids=",$merges," 'index(ids, "," $1 ",") { s = tolower($2) " (job " $1 ")" } END { print s }' <<<"$queued")
if [[ -f $out/image.exr && $unfinished == 0 ]]; then
    echo "merge: done ($out/image.exr)"
elif [[ -n $merge_state ]]; then
    echo "merge: $merge_state"
else
    echo "merge: not done (see $out/merge.log)"
fi
if ((${#missing[@]} > 0)); then
    list=$(IFS=,; echo "${missing[*]}")
    echo "render the missing bands again, and merge: ${command/ BANDS / $list }"
fi
[[ -f $out/image.exr && $unfinished == 0 ]]
