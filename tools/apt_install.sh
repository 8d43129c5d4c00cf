#!/usr/bin/env bash
# Installs the Debian packages named that are not installed yet, where apt-get can (as root, or
# through sudo without a password); elsewhere it warns and goes on: what needs them skips, saying why.
#   bash tools/apt_install.sh PACKAGE...
set -uo pipefail
missing=()
for package in "$@"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
[ ${#missing[@]} -eq 0 ] && exit 0
SUDO=""
if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; fi
if command -v apt-get >/dev/null 2>&1 \
    && { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"; } >/dev/null 2>&1
then
    echo "installed ${missing[*]}"
else
    echo "warning: could not install ${missing[*]} (Debian packages); what needs them will skip" >&2
fi
exit 0
