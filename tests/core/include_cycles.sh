#!/bin/sh
# include_cycles.sh CORE_DIR -- fails when two files of core/ include each other,
# directly or through others (docs/design/step.md, "Dependencies"). A file pair
# (name.c, name.h) is one node; tsort (coreutils) names the files of any loop.
set -eu
core=$1
cd "$core"
edges=$(for f in $(find . -name '*.[ch]' | sort); do
    dir=$(dirname "$f")
    from=${f%.*}
    sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f" |
        while read -r inc; do
            to=$(realpath -m --relative-to=. "$dir/$inc")
            case $to in ../*) continue ;; esac
            to=./${to%.*}
            if [ "$to" != "$from" ]; then echo "$from $to"; fi
        done
    echo "$from $from"
done)
count=$(printf '%s\n' "$edges" | awk '$1 != $2' | wc -l)
err=$(mktemp)
if ! printf '%s\n' "$edges" | tsort > /dev/null 2> "$err"; then
    echo "include cycle among core files:" >&2
    cat "$err" >&2
    rm -f "$err"
    exit 1
fi
rm -f "$err"
echo "no include cycle: $count includes between core files"
