#!/bin/bash
# Run a command where no Python can be found: a machine with no Python installed, as far as the
# command can tell. Run it in a private mount namespace (the mounts vanish with it):
#
#   unshare -m tests/c_host/hide_python.sh [PATH...] -- COMMAND [ARG...]
#   unshare -r -m ...   (the same without root, where user namespaces are allowed)
#
# Every directory below, and each PATH given, is covered with an empty tmpfs; every file is covered
# with /dev/null (an empty file, which no loader or shell accepts). Pass the test checkout, the
# deltafmi build cache, the running virtual environment and its base interpreter as PATHs; what
# the COMMAND needs (the host binary, the unpacked FMU) must lie outside all of them.
set -e
extra=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do extra+=("$1"); shift; done
[ "$1" = "--" ] && shift
[ $# -gt 0 ] || { echo "usage: hide_python.sh [PATH...] -- COMMAND [ARG...]" >&2; exit 2; }

shopt -s nullglob
lib=(/usr/lib/x86_64-linux-gnu /lib/x86_64-linux-gnu /usr/lib64 /usr/local/lib)
dirs=(/root/.pyenv "$HOME/.pyenv" /usr/lib/python3* /usr/local/lib/python3* /opt/hostedtoolcache/Python /opt/conda)
files=(/usr/bin/python* /usr/local/bin/python* /bin/python*)
# the interpreter and the libraries a bundle carries: hidden so that only the bundled ones can serve
for d in "${lib[@]}"; do
  files+=("$d"/libpython3* "$d"/libffi.so* "$d"/libz.so* "$d"/libcrypto.so* "$d"/libssl.so* "$d"/libstdc++.so*
          "$d"/libbz2.so* "$d"/liblzma.so* "$d"/libgfortran.so* "$d"/libquadmath.so* "$d"/libopenblas*.so*
          "$d"/libsundials*)
done

hide() {
  if [ -L "$1" ]; then return 0; fi  # a symbolic link leads to a file or folder hidden itself
  if [ -d "$1" ]; then mount -t tmpfs -o ro tmpfs "$1"
  elif [ -e "$1" ]; then mount --bind /dev/null "$1"
  fi
}
for path in "${dirs[@]}" "${files[@]}"; do hide "$path"; done
for path in "${extra[@]}"; do
  # a symbolic link given explicitly (a venv's python3 -> the base interpreter) is followed
  target=$(readlink -f "$path" || true)
  [ -n "$target" ] && hide "$target"
done
exec "$@"
