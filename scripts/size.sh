#!/usr/bin/env bash
# Flash and static RAM of a firmware ELF against the ATmega2560, failing above
# the project's budget, set a little above what the firmware takes so that the
# savings of issue 14 stay made (62184 B of flash and 2905 B of RAM for
# paper_2seg, 62310 B and 3602 B for trio_3seg, the largest robot, which the
# budget covers: each robot's firmware keeps per-tendon and per-sensor state
# for its own table; the survey at three quarters of the top tension took
# 26 B, and firmware/link_order.txt refined after it -52 B). 1252 B of it and 3 B of RAM are the board's held pulls
# (`survey T H`, issue 17), with firmware/link_order.txt refined for them
# (-10 B): 60948 B / 2902 B and 61090 B / 3599 B before them; 61920 B /
# 3960 B and 62016 B / 3960 B before the round that sized the firmware to
# its robot, sent the servo bus's requests from the master's buffer and
# placed the functions in the order of firmware/link_order.txt; how the
# flash got here, step by step: docs/benchmarks.md, item 6. Issue 14's goal
# is 48 KB / 3 KB: lower these as savings land.
set -euo pipefail
elf=$1
flash_cap=262144 ram_cap=8192
flash_max=62320 ram_max=3608
read -r text data bss noinit < <(avr-size -A "$elf" | awk '
    $1==".text"{t=$2} $1==".data"{d=$2} $1==".bss"{b=$2} $1==".noinit"{n=$2}
    END{print t+0, d+0, b+0, n+0}')
flash=$((text + data))
ram=$((data + bss + noinit))
printf 'flash: %6d bytes (%4.1f %% of %d, budget %d)\n' $flash "$(awk "BEGIN{print 100*$flash/$flash_cap}")" $flash_cap $flash_max
printf 'ram:   %6d bytes (%4.1f %% of %d, budget %d) data %d bss %d noinit %d\n' $ram "$(awk "BEGIN{print 100*$ram/$ram_cap}")" $ram_cap $ram_max $data $bss $noinit
if ((flash > flash_max)); then echo "size: flash over budget" >&2; exit 1; fi
if ((ram > ram_max)); then echo "size: static RAM over budget" >&2; exit 1; fi
