#!/usr/bin/env bash
# Installs everything hallhome needs on a Debian (bookworm) machine:
# the Debian packages in scripts/apt-packages.txt and a Python venv in .venv
# with the host toolkit installed in editable mode. Safe and fast to re-run.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

mapfile -t wanted < <(grep -v '^\s*#' scripts/apt-packages.txt | awk 'NF {print $1}')
missing=()
for pkg in "${wanted[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed'; then
        missing+=("$pkg")
    fi
done

if ((${#missing[@]})); then
    echo "bootstrap: installing Debian packages: ${missing[*]}"
    apt_cmd=(apt-get install -y --no-install-recommends "${missing[@]}")
    if [[ $(id -u) -eq 0 ]]; then
        sudo_cmd=()
    elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
        sudo_cmd=(sudo)
    else
        echo "bootstrap: need root to install packages. Run:" >&2
        echo "  sudo apt-get update && sudo ${apt_cmd[*]}" >&2
        exit 1
    fi
    export DEBIAN_FRONTEND=noninteractive
    "${sudo_cmd[@]}" apt-get update -qq
    "${sudo_cmd[@]}" "${apt_cmd[@]}" -qq
else
    echo "bootstrap: Debian packages present"
fi

# The venv: prefer the first python3 on PATH that is >= 3.11 and has venv.
venv=.venv
if [[ ! -x $venv/bin/python ]]; then
    py=""
    for cand in python3 /usr/bin/python3; do
        if command -v "$cand" >/dev/null &&
            "$cand" -c 'import sys, venv, ensurepip; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
            py=$cand
            break
        fi
    done
    if [[ -z $py ]]; then
        echo "bootstrap: no Python >= 3.11 with venv found" >&2
        exit 1
    fi
    echo "bootstrap: creating $venv with $($py --version)"
    "$py" -m venv "$venv"
fi
echo "bootstrap: installing host_tools into $venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check -e "host_tools[test]"
echo "bootstrap: done"
