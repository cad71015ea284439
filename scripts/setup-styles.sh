#!/usr/bin/env bash
# Fetch real paintings to use as styles in tests, benchmarks and `--style painting:KEY`, from
# Debian's gcompris-qt-data (GPL-3.0-or-later packaging of public-domain works from the
# WebMuseum): its `paintings` puzzle ships each painting as jigsaw pieces inside a Qt resource
# file (/usr/share/gcompris-qt/rcc/paintings.rcc). Every piece of the six paintings below is
# taken out, verified by SHA-256 and put in the style directory the Rust side reads, which
# puts each painting back together (trainer/stylize/src/paintings.rs) as KEY.png:
#   $SNERF_STYLES, else ${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles
#   vangogh     gogh_auvert_{1..6}.webp                  Vincent van Gogh, Village Street in Auvers (1890)
#   renoir      renoir-moulin_de_la_galette-{1..6}.webp  Pierre-Auguste Renoir, Bal du moulin de la Galette (1876)
#   kandinsky   kandinky_{1..8}.webp                     Wassily Kandinsky, Composition VIII (1923)
#   greatwave   GreatWave_{a..d}{1..3}.webp              Katsushika Hokusai, The Great Wave off Kanagawa (1823-1829)
#   cassatt     cassat_summertime_{1..6}.webp            Mary Cassatt, Summertime (1894)
#   bazille     bazille_rampart_{1..6}.webp              Frederic Bazille, The Ramparts at Aigues-Mortes (1867)
# Idempotent: does nothing when the files are already there with the right hashes. Uses the
# installed package when present, else `apt-get download` (no root needed) into a temporary
# directory. Exits non-zero only when the paintings cannot be obtained.
set -euo pipefail

STYLES_DIR="${SNERF_STYLES:-${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles}"
RCC_IN_PACKAGE=usr/share/gcompris-qt/rcc/paintings.rcc
RCC_SHA256=1276d4f9c26f94ec130833c03bea5185f61b4f986df6981182cdb1be69e9db98
# Same constants as trainer/stylize/src/paintings.rs.
declare -A SHA256=(
  [gogh_auvert_1.webp]=81f84ce20f31486197f459635ddeef042344c694af6fa130418a36b1d45a6904
  [gogh_auvert_2.webp]=c4518c2389a6c572ad1ea623479e7a5030f3aa59dedc9c4cac73d55cda96c86c
  [gogh_auvert_3.webp]=1aefb708e7c36a0e4c7c718e8cd2fd37d8321d7a4018d916f149314e4d4bfb98
  [gogh_auvert_4.webp]=8cdc157e260d5d1864198c72951275c405b6f74568c836f285781caba0895f3c
  [gogh_auvert_5.webp]=4bcb1e64c44022b79a56aba86643fdca26bad5d2a908c56400240fe9f08f1142
  [gogh_auvert_6.webp]=b8ab1e32b422995ced0bce842a126da84a9db9d3eaba003934eee3c7ed915204
  [renoir-moulin_de_la_galette-1.webp]=78880d194c3be92da64d89bca581e09c699303f7848c84f653f6cca0a14e2422
  [renoir-moulin_de_la_galette-2.webp]=297bdebac908b464b7b76a3555cbfa2192816bc660859dadc6041caae5f55617
  [renoir-moulin_de_la_galette-3.webp]=185c721373176d28f518a5625894def2389bd29b0be65ddef802a48e34898c57
  [renoir-moulin_de_la_galette-4.webp]=182d1f65643f33d6583b9a3b3a6831af42dc0f0e11c65414e5656e13e619dbf7
  [renoir-moulin_de_la_galette-5.webp]=593aaecdb2bc1cfbd6524348538abdd82242f4d70aaeb20a3b932d494e2d9c1f
  [renoir-moulin_de_la_galette-6.webp]=e9358ce944f2f77fc618d6c3d357e3e3aec4dc7626bff40be1b994ad2bf640a0
  [kandinky_1.webp]=67bcd29206ed353a21f6ea5526d1b4f77f4647f6d7e1d8f3f4bef6c2298b65c5
  [kandinky_2.webp]=0315468377f7f36584bb0e46e1e201a525aa7c1bc9d1685af7990248c68a7255
  [kandinky_3.webp]=f9518aa6512a0e454a22e850f77d43ed7509e8a098fb5dad5ad22c10fd32e51b
  [kandinky_4.webp]=92e3ebbaa42df5af6129dcb749a0f6cfa9749a469410077b6d8d00ac2b886db9
  [kandinky_5.webp]=9fab6cfbfb69cb6f4089ba1bf81cf40e32b4b61125ca1ef9ae50c1461362377f
  [kandinky_6.webp]=4d96b7997185047abc6ca0c77d9c742c9b9aea6514e14e5cb7865d4b723aff54
  [kandinky_7.webp]=b7567aacb05ec786f11d4a0da407b95d4a1b38675b2462646cd515e865cce500
  [kandinky_8.webp]=0c7b9d5d01972843c9a4049007bb8b22c8ab352f656782d5fd7dd4dfb9cea297
  [GreatWave_a1.webp]=0e83968ebf461cba0bc90021e78ac3934ed41181a1c2f3d587350c41f5bdc7e1
  [GreatWave_a2.webp]=35110e1c3ed5ea6aef169dacf16001972dea04300484bb503785a61b71e41bf9
  [GreatWave_a3.webp]=897aeb56b0e2c527b02c40d5eeda7c101eebeb3e432770bf89861d9aa0e6414d
  [GreatWave_b1.webp]=28b72a3a9eb6e798eecfda187705e1e56955a5e19b18006a0b33aed8ca48aff3
  [GreatWave_b2.webp]=342fea36ea63073282803f7e36fe770b5d8e2f1906c512e19c24af9e68426915
  [GreatWave_b3.webp]=6b6837959b9ab7e89a689be1ebdcea8b53edb52e5b4f974953b5b7dc50b13b2e
  [GreatWave_c1.webp]=67422ca616ef0395aac3b3fa5acba56d4aa6a0e0e1efee40f33a75177966b723
  [GreatWave_c2.webp]=6679166308a66aa4ab4c0d3633838074a0e322ae40486b2a16e5cfa347922eff
  [GreatWave_c3.webp]=af0f79b1302665cd5e6c0a83de694409c26a6d132a09bee57b4e91f7b3ac34b6
  [GreatWave_d1.webp]=8ce5241159d5e659e14f223caefa369ce625696cc0e35a66bc0052f124cd0fcb
  [GreatWave_d2.webp]=5d457790ea88e216813ec4405086ebf8883c657c7061148edfe565458a04b1c4
  [GreatWave_d3.webp]=2491c11e9208b6b2161acd95cb9eb646f88184f48ae6bae88119221406141a82
  [cassat_summertime_1.webp]=12250ef3b55af74fc45b2c3597d9bf4d02675650abdbc8bf0885635704065e16
  [cassat_summertime_2.webp]=d17de55174fa12b04db04b0bfed25d9176ce912e643b1fe1dce31532eec7eb7f
  [cassat_summertime_3.webp]=13f4baa81dc32bec7494b524d551736acbaa99e7f6d9ab233ba6f90dc71814f6
  [cassat_summertime_4.webp]=48ada16b2b17e20e74875cb429374c2af58d0c43c0b881d9f941c91e15e96478
  [cassat_summertime_5.webp]=3d3cc54575c97fc4fc451ea5e65aa40ecb7c762ed2b0632fd4d44dc42ad9f62f
  [cassat_summertime_6.webp]=a9eb351191253246cd20c5c619e9f699747a547f881bf17f3341dca4cacb8d76
  [bazille_rampart_1.webp]=6a16546cd624d715e7c9f29133f0667bb4e07a035ebaafb5c392f6811c30cd52
  [bazille_rampart_2.webp]=365fd7e758887e5aa6390c067e57773e0e5aaff6038436dcb86c1d40c08e25bb
  [bazille_rampart_3.webp]=1c0393db1da6c10eabac5b1935068e64836a6d9724b010daa51cbdbde02b32b2
  [bazille_rampart_4.webp]=3508ea1d28bcbc3e34ef11013e73c587c81608e74649b5efd4b2f3d20da1dc0e
  [bazille_rampart_5.webp]=80bf7e3bd9552d8f1df5b66e5f2936856a9bc9d8f96d0d530f7b4e2dc2869577
  [bazille_rampart_6.webp]=7f0d19fc2fa3260ed976ee209bd5a1a5d3fe373e936e5d2451d864682a9d5f4a
)

log() { echo "setup-styles: $*" >&2; }

PY=python3
command -v "$PY" >/dev/null 2>&1 || PY=python

file_ok() { # path expected-hash
  [[ -f "$1" ]] && [[ "$(sha256sum "$1" | cut -d' ' -f1)" == "$2" ]]
}

all_present() {
  local name
  for name in "${!SHA256[@]}"; do
    file_ok "$STYLES_DIR/$name" "${SHA256[$name]}" || return 1
  done
}

# Qt resource file (rcc, format 1-3) reader: writes the named files found anywhere in it.
extract_rcc() { # rcc-file out-dir names...
  "$PY" - "$@" <<'PYEOF'
import struct, sys, zlib, os
path, out, wanted = sys.argv[1], sys.argv[2], set(sys.argv[3:])
b = open(path, 'rb').read()
if b[:4] != b'qres':
    sys.exit(f"{path}: not a Qt resource file")
ver, tree, data, names = struct.unpack('>IIII', b[4:20])
node = 22 if ver >= 2 else 14
def name(off):
    n, _ = struct.unpack('>HI', b[names + off:names + off + 6])
    return b[names + off + 6:names + off + 6 + 2 * n].decode('utf-16-be')
found = set()
stack = [0]
while stack:
    i = stack.pop()
    o = tree + i * node
    noff, flags = struct.unpack('>IH', b[o:o + 6])
    if flags & 2:
        cnt, first = struct.unpack('>II', b[o + 6:o + 14])
        stack.extend(range(first, first + cnt))
        continue
    nm = name(noff)
    if nm not in wanted:
        continue
    doff, = struct.unpack('>I', b[o + 10:o + 14])
    sz, = struct.unpack('>I', b[data + doff:data + doff + 4])
    blob = b[data + doff + 4:data + doff + 4 + sz]
    if flags & 1:
        blob = zlib.decompress(blob[4:])
    elif flags & 4:
        sys.exit(f"{path}: {nm} is zstd-compressed; not supported")
    with open(os.path.join(out, nm), 'wb') as f:
        f.write(blob)
    found.add(nm)
missing = wanted - found
if missing:
    sys.exit(f"{path}: missing {', '.join(sorted(missing))}")
PYEOF
}

fetch_paintings() {
  local tmp rcc
  tmp="$(mktemp -d)"
  # shellcheck disable=SC2064
  trap "rm -rf '$tmp'" EXIT
  if file_ok "/$RCC_IN_PACKAGE" "$RCC_SHA256"; then
    rcc="/$RCC_IN_PACKAGE"
  else
    log "downloading Debian package gcompris-qt-data (44 MB)"
    if ! (cd "$tmp" && apt-get download gcompris-qt-data >/dev/null 2>&1); then
      # An old package list may not know the package yet.
      (apt-get update -qq >/dev/null 2>&1 || true)
      (cd "$tmp" && apt-get download gcompris-qt-data >/dev/null) || { log "error: apt-get download gcompris-qt-data failed"; return 1; }
    fi
    dpkg-deb --fsys-tarfile "$tmp"/gcompris-qt-data_*.deb | tar -x -C "$tmp" "./$RCC_IN_PACKAGE"
    rcc="$tmp/$RCC_IN_PACKAGE"
    if ! file_ok "$rcc" "$RCC_SHA256"; then
      log "warning: paintings.rcc differs from the known version ($(sha256sum "$rcc" | cut -d' ' -f1)); checking the paintings themselves"
    fi
  fi
  mkdir -p "$tmp/out" "$STYLES_DIR"
  extract_rcc "$rcc" "$tmp/out" "${!SHA256[@]}"
  local name
  for name in "${!SHA256[@]}"; do
    if ! file_ok "$tmp/out/$name" "${SHA256[$name]}"; then
      log "error: $name has SHA-256 $(sha256sum "$tmp/out/$name" | cut -d' ' -f1), expected ${SHA256[$name]}"
      return 1
    fi
    cp "$tmp/out/$name" "$STYLES_DIR/.$name.tmp"
    mv -f "$STYLES_DIR/.$name.tmp" "$STYLES_DIR/$name"
  done
}

if all_present; then
  log "paintings already in $STYLES_DIR"
else
  fetch_paintings || exit 1
  all_present || { log "error: paintings in $STYLES_DIR still fail verification"; exit 1; }
  log "paintings installed in $STYLES_DIR"
fi
echo "$STYLES_DIR"
