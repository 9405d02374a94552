#!/usr/bin/env bash
# Runs every libFuzzer target built in $1 with the given libFuzzer options;
# the corpus of each lives in build/ (kept between runs, never committed).
set -euo pipefail
dir=$1
shift
shopt -s nullglob
targets=("$dir"/fuzz_*)
if ((${#targets[@]} == 0)); then
    echo "fuzz: no fuzz targets"
    exit 0
fi
for t in "${targets[@]}"; do
    [[ -x $t ]] || continue
    name=$(basename "$t")
    corpus="$dir/corpus/$name"
    mkdir -p "$corpus"
    log="$dir/$name.log"
    if ! "$t" "$corpus" "$@" -print_final_stats=1 >"$log" 2>&1; then
        tail -n 60 "$log"
        echo "fuzz: $name FAILED (full log: $log)" >&2
        exit 1
    fi
    echo "fuzz: $name ok, $(grep -o 'number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$') inputs ($*)"
done
