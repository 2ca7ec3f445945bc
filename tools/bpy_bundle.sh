#!/bin/bash
# Carry this machine's Blender (the pip bpy module, which needs Python 3.11) to a GPU machine that has
# neither, in parts small enough for a device call's 64 MiB, and run a module with it there.
#
#   tools/bpy_bundle.sh pack DIR          here: DIR/bundle.part_* (about 250 MB in 44 MiB parts) and DIR/bundle.sha256
#   tools/bpy_bundle.sh add PART          there, once per part, in order: appends it to /tmp/bpy_bundle.tar.xz
#   tools/bpy_bundle.sh run MODULE ARGS   there: unpacks once, then python3.11 -m MODULE ARGS from the repository root
#
# The bundle holds Python 3.11 (standard library without its tests), numpy, bpy without the USD
# Python modules, the unused add-ons and the AMD kernels, and the X11/GL client libraries bpy links
# (glvnd's libEGL among them; the NVIDIA driver supplies the vendor side). bench/material/native_gpu.py says
# what to run with it. A machine given back loses the parts: add and run in back-to-back calls.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bundle=/tmp/bpy_bundle.tar.xz
root=/tmp/bpy_bundle

pack() {
    local out=$1 stage site
    stage=$(mktemp -d)
    site=$("$here/.venv/bin/python" -c "import numpy, pathlib; print(pathlib.Path(numpy.__file__).parents[1])")
    local py
    py=$("$here/.venv/bin/python" -c "import sys; print(sys.base_prefix)")
    mkdir -p "$stage/py/bin" "$stage/py/lib" "$stage/site" "$stage/sys" "$out"
    cp "$py/bin/python3.11" "$stage/py/bin/"
    cp "$py/lib/libpython3.11.so.1.0" "$stage/py/lib/"
    tar -C "$py/lib" -cf - --exclude=test --exclude=tests --exclude=idlelib --exclude=tkinter --exclude=ensurepip \
        --exclude=turtledemo --exclude=site-packages --exclude=__pycache__ --exclude=lib2to3 --exclude='config-3.11*' \
        python3.11 | tar -C "$stage/py/lib" -xf -
    tar -C "$site" -cf - --exclude=__pycache__ --exclude='*gfx*' --exclude='kernel_sm_[5-8]*' --exclude='kernel_sm_120*' \
        --exclude=pxr --exclude=MaterialX --exclude=rigify --exclude=io_scene_gltf2 --exclude=io_scene_fbx \
        --exclude=bpy/5.0/datafiles/assets --exclude=bpy/5.0/datafiles/locale \
        --exclude='libOpenImageDenoise_device_*' numpy numpy.libs bpy | tar -C "$stage/site" -xf -
    for lib in libX11.so.6 libXrender.so.1 libXfixes.so.3 libXi.so.6 libxkbcommon.so.0 libxcb.so.1 libXext.so.6 \
               libSM.so.6 libICE.so.6 libXau.so.6 libXdmcp.so.6 libuuid.so.1 libbsd.so.0 libmd.so.0 libX11-xcb.so.1 \
               libXxf86vm.so.1 libGL.so.1 libGLX.so.0 libGLdispatch.so.0 libEGL.so.1 libOpenGL.so.0; do
        cp -L "/lib/x86_64-linux-gnu/$lib" "$stage/sys/"
    done
    tar -C "$stage" -cf - . | xz -T0 -7 > "$out/bundle.tar.xz"
    rm -rf "$stage"
    sha256sum "$out/bundle.tar.xz" | cut -c1-64 > "$out/bundle.sha256"
    split -b 44M -a 1 "$out/bundle.tar.xz" "$out/bundle.part_"
    rm "$out/bundle.tar.xz"
    ls -l "$out"
}

run() {
    if [ ! -x "$root/py/bin/python3.11" ]; then
        mkdir -p "$root" && xz -T0 -dc "$bundle" | tar -C "$root" -xf -
    fi
    export LD_LIBRARY_PATH="$root/py/lib:$root/sys:/usr/local/nvidia/lib64:/usr/local/nvidia/lib:${LD_LIBRARY_PATH:-}"
    export PYTHONHOME="$root/py" PYTHONPATH="$root/site:$here" HOME=/tmp/bpy_home BLENDER_USER_RESOURCES=/tmp/bpy_home/blender
    export CUDA_CACHE_MAXSIZE=4294967296 PYTHONUNBUFFERED=1  # Cycles' CUDA kernel is JIT-compiled on sm_90: keep it
    local egl=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    [ -f "$egl" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$egl
    cd "$here" && exec "$root/py/bin/python3.11" -m "$@"
}

case ${1:-} in
    pack) pack "$2" ;;
    add) cat "$2" >> "$bundle" && ls -l "$bundle" ;;
    run) shift && run "$@" ;;
    *) sed -n '2,9p' "$0" && exit 2 ;;
esac
