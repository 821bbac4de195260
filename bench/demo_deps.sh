#!/usr/bin/env bash
# What `make demo` and `make test` install on a fresh Debian 12 (#35), without a fresh machine:
# apt simulates both package sets against a dpkg status that holds only a minimal base (this
# machine's Priority: required and Essential packages, apt, and their dependencies: about what
# the debian:12 image holds). Prints the packages and download size of each set. With a
# BUILD_DIR of a `make demo` configuration (tests and benchmarks off) built for `pneuma`, it also
# checks the demo set against what that build used: every system header in its dependency log,
# every library it links and every library `pneuma` loads must belong to a package the demo set
# installs (or the base); it lists any that does not and exits 1.
#   bench/demo_deps.sh [BUILD_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/pneuma-demo-deps.XXXXXX)
trap 'rm -rf "$work"' EXIT

# The minimal base: required and essential packages, apt, and what they depend on (installed here).
/usr/bin/python3 - "$work/status" <<'PY'
import re, sys
stanzas = open('/var/lib/dpkg/status').read().strip().split('\n\n')
fields = {}
for st in stanzas:
    f = dict(m.groups() for m in re.finditer(r'^([A-Za-z-]+): ?(.*)$', st, re.M))
    fields[f['Package']] = (f, st)
provides = {}
for name, (f, _) in fields.items():
    for p in f.get('Provides', '').split(','):
        if p.strip():
            provides.setdefault(p.strip().split(' ')[0], name)
keep = {n for n, (f, _) in fields.items() if f.get('Priority') == 'required' or f.get('Essential') == 'yes' or n == 'apt'}
todo = list(keep)
while todo:
    f = fields[todo.pop()][0]
    for key in ('Depends', 'Pre-Depends'):
        for alternatives in filter(None, (a.strip() for a in f.get(key, '').split(','))):
            for a in alternatives.split('|'):
                name = a.strip().split(' ')[0].split(':')[0]
                found = name if name in fields else provides.get(name)
                if found:
                    if found not in keep:
                        keep.add(found)
                        todo.append(found)
                    break
open(sys.argv[1], 'w').write('\n\n'.join(fields[n][1] for n in sorted(keep)) + '\n')
print(f'base: {len(keep)} packages', file=sys.stderr)
PY

list() { sed -n "/^$1=(/,/^)/p" "$root/scripts/install-deps" | sed -e 's/#.*//' -e "s/^$1=(//" -e 's/)$//' | tr -s ' \n' ' '; }
demo=$(list demo_packages)
full="$demo $(list engine_packages) $(list test_packages)"
apt_opts=(-o "Dir::State::status=$work/status" -o "Dir::Cache::archives=$work/archives" --no-install-recommends)
mkdir -p "$work/archives/partial"
for set in demo full; do
  # shellcheck disable=SC2086
  apt-get --print-uris -y "${apt_opts[@]}" install ${!set} 2>/dev/null |
    awk -v set="$set" '/^\x27http/ {n++; bytes += $3} END {printf "%s: %d packages, %.1f MB to download\n", set, n, bytes / 1e6}'
done

[ $# -ge 1 ] || exit 0
build=$(realpath "$1")
# shellcheck disable=SC2086
apt-get -s "${apt_opts[@]}" install $demo 2>/dev/null | awk '/^Inst/ {print $2}' >"$work/closure"
sed -n 's/^Package: //p' "$work/status" >>"$work/closure"
sort -u "$work/closure" -o "$work/closure"
{
  (cd "$build" && ninja -t deps) | sed -n 's|^ *\(/usr/.*\)|\1|p'
  grep -ohE '/usr/[^ ;"*]+\.(so|a)(\.[0-9]+)*\b' "$build/build.ninja"
  ldd "$build/cli/pneuma" | awk '/=>/ {print $3}'
} | /usr/bin/python3 -c 'import os, sys; [print(os.path.normpath(f)) for f in sys.stdin.read().split() if os.path.isfile(f)]' |
  sed 's|^/lib/|/usr/lib/|' | sort -u >"$work/files"
# dpkg knows some libraries by their /lib path (merged /usr); compilers by their alternatives.
owners() { { xargs -r dpkg -S 2>/dev/null || true; } | sed 's/: \/.*//' | tr ',' '\n' | sed 's/^ *//; s/:.*//'; }
{
  owners <"$work/files"
  { xargs -r -a "$work/files" dpkg -S 2>&1 >/dev/null || true; } | sed -n 's/.*pattern \/usr\/lib\//\/lib\//p' | owners
} | sort -u >"$work/owners"
missing=$(comm -23 "$work/owners" "$work/closure")
echo "demo build: $(wc -l <"$work/files") system files read, from $(wc -l <"$work/owners") packages"
if [ -n "$missing" ]; then
  echo "not in the demo set: $missing"
  exit 1
fi
echo "every one of them is in the demo set"
