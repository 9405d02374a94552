#!/usr/bin/env bash
# Flash and static RAM of a firmware ELF against the ATmega2560, failing above
# the project's budget. The budget sits a little above trio_3seg, the largest
# robot (each robot's firmware keeps per-tendon and per-sensor state for its
# own table): 59092 B of flash and 3063 B of RAM; paper_2seg 58944 B / 2512 B.
# How the firmware got here, step by step, and what each step cost or saved:
# docs/benchmarks.md, item 6. Issue 14's goal is 48 KB / 3 KB: the RAM budget
# is the goal's 3072 B; lower the flash budget as savings land.
set -euo pipefail
elf=$1
flash_cap=262144 ram_cap=8192
flash_max=59110 ram_max=3072
read -r text data bss noinit < <(avr-size -A "$elf" | awk '
    $1==".text"{t=$2} $1==".data"{d=$2} $1==".bss"{b=$2} $1==".noinit"{n=$2}
    END{print t+0, d+0, b+0, n+0}')
flash=$((text + data))
ram=$((data + bss + noinit))
printf 'flash: %6d bytes (%4.1f %% of %d, budget %d)\n' $flash "$(awk "BEGIN{print 100*$flash/$flash_cap}")" $flash_cap $flash_max
printf 'ram:   %6d bytes (%4.1f %% of %d, budget %d) data %d bss %d noinit %d\n' $ram "$(awk "BEGIN{print 100*$ram/$ram_cap}")" $ram_cap $ram_max $data $bss $noinit
if ((flash > flash_max)); then echo "size: flash over budget" >&2; exit 1; fi
if ((ram > ram_max)); then echo "size: static RAM over budget" >&2; exit 1; fi
