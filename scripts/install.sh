#!/usr/bin/env bash
# Installs Parallax's C/C++ development files into PREFIX from libraries already built:
#
#   scripts/install.sh PREFIX [LIBDIR]
#
# LIBDIR holds libparallax.so (.dylib) and/or libparallax.a; default target/release (after
# `cargo build --release`). Installs
#   PREFIX/lib/libparallax.{so,dylib,a}       what LIBDIR has of them
#   PREFIX/include/parallax.h, parallax.hpp   the C header and the C++17 wrapper
#   PREFIX/lib/pkgconfig/parallax.pc          pkg-config
#   PREFIX/lib/cmake/Parallax/                find_package(Parallax) → Parallax::parallax(_static)
# with the version taken from Cargo.toml. Builds nothing; needs only bash, sed and coreutils.
set -euo pipefail

if [ $# -lt 1 ] || [ $# -gt 2 ]; then
    echo "usage: $0 PREFIX [LIBDIR]" >&2
    exit 2
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
prefix="$1"
libdir="${2:-$root/target/release}"
mkdir -p "$prefix"
prefix="$(cd "$prefix" && pwd -P)"

# The [package] version of Cargo.toml: the first `version = "…"` line.
version="$(sed -n 's/^version *= *"\([^"]*\)".*/\1/p' "$root/Cargo.toml" | head -n 1)"
if [ -z "$version" ]; then
    echo "$0: no version found in $root/Cargo.toml" >&2
    exit 1
fi

# What a static libparallax.a needs from the system (`rustc --print native-static-libs` for the
# Rust standard library and wgpu, which opens Vulkan with dlopen).
case "$(uname -s)" in
    Darwin) static_libs="-framework Security -framework CoreFoundation -framework Metal -framework QuartzCore -framework Foundation -lobjc -liconv -lSystem -lc -lm" ;;
    *) static_libs="-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc" ;;
esac
# The same list as CMake link items ("-lm" → "m", "-framework X" → "-framework X").
cmake_static_libs="$(printf '%s\n' $static_libs | sed -e '/^-framework$/{N;s/\n/ /}' -e 's/^-l//' | paste -sd ';' -)"

found=0
mkdir -p "$prefix/lib" "$prefix/include" "$prefix/lib/pkgconfig" "$prefix/lib/cmake/Parallax"
for lib in libparallax.so libparallax.dylib libparallax.a; do
    if [ -f "$libdir/$lib" ]; then
        cp -f "$libdir/$lib" "$prefix/lib/$lib"
        found=1
    fi
done
if [ "$found" = 0 ]; then
    echo "$0: no libparallax in $libdir: run \`cargo build --release\` first, or name LIBDIR" >&2
    exit 1
fi
cp -f "$root/include/parallax.h" "$root/bindings/cpp/parallax.hpp" "$prefix/include/"

fill() {
    sed -e "s|@VERSION@|$version|g" -e "s|@PREFIX@|$prefix|g" \
        -e "s|@STATIC_LIBS@|$static_libs|g" -e "s|@CMAKE_STATIC_LIBS@|$cmake_static_libs|g" \
        "$1" >"$2"
}
fill "$root/packaging/parallax.pc.in" "$prefix/lib/pkgconfig/parallax.pc"
fill "$root/packaging/ParallaxConfig.cmake.in" "$prefix/lib/cmake/Parallax/ParallaxConfig.cmake"
fill "$root/packaging/ParallaxConfigVersion.cmake.in" \
    "$prefix/lib/cmake/Parallax/ParallaxConfigVersion.cmake"
echo "installed Parallax $version into $prefix"
