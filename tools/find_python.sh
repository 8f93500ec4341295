#!/bin/sh
# Prints the path of a working Python X.Y (with venv and ensurepip), for
# `make`: the first of
#   $2 (a given interpreter, e.g. `make PYTHON313=/path/to/python3.13`),
#   pyenv's X.Y (`pyenv prefix X.Y`; also without pyenv on PATH, under
#   $PYENV_ROOT or ~/.pyenv/versions, newest X.Y.Z first),
#   pythonX.Y on PATH (a pyenv shim that is not selected fails the check and
#   is skipped), /usr/local/bin, /usr/bin, /opt/homebrew/bin.
# Fails, saying what to install, when none works.
# Usage: sh tools/find_python.sh X.Y [INTERPRETER]
set -u
want="$1"
given="${2:-}"
major="${want%%.*}"
minor="${want#*.}"

works() {
    [ -n "$1" ] && "$1" -c "import sys, venv, ensurepip
sys.exit(sys.version_info[:2] != ($major, $minor))" >/dev/null 2>&1
}

if [ -n "$given" ]; then
    if works "$given"; then
        command -v "$given" 2>/dev/null || echo "$given"
        exit 0
    fi
    echo "error: $given is not a working Python $want with the venv module" >&2
    exit 1
fi

candidates=""
if command -v pyenv >/dev/null 2>&1; then
    prefix=$(pyenv prefix "$want" 2>/dev/null | head -n 1)
    [ -n "$prefix" ] && candidates="$prefix/bin/python$want"
fi
root="${PYENV_ROOT:-$HOME/.pyenv}"
if [ -d "$root/versions" ]; then
    for dir in $(ls -d "$root/versions/$want" "$root/versions/$want".* 2>/dev/null | sort -r -V); do
        candidates="$candidates $dir/bin/python$want"
    done
fi
onpath=$(command -v "python$want" 2>/dev/null || true)
candidates="$candidates $onpath /usr/local/bin/python$want /usr/bin/python$want /opt/homebrew/bin/python$want"

for candidate in $candidates; do
    if works "$candidate"; then
        echo "$candidate"
        exit 0
    fi
done

cat >&2 <<MSG
error: no working Python $want found (looked at pyenv's $want, python$want on PATH,
/usr/local/bin, /usr/bin, /opt/homebrew/bin). Install one, then run make again:
  pyenv:          pyenv install $want
  Debian/Ubuntu:  apt-get install python$want python$want-venv
  macOS:          brew install python@$want
or name one: make PYTHON${major}${minor}=/path/to/python$want
MSG
exit 1
