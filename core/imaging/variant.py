"""Pick Mitsuba's variant at run time: ``llvm_ad_rgb`` when LLVM works, else ``scalar_rgb``;
and ``shape_index``, the id a variant's ``aov`` integrator gives a shape.

Dr.Jit's LLVM backend needs libLLVM >= 16 (LLVM 15 crashes the process, 14 is refused), so the
check runs in a child process and, where several libLLVM versions are installed, points
``DRJIT_LIBLLVM_PATH`` at the newest one first.
"""

from __future__ import annotations

import functools
import glob
import logging
import os
import re
import subprocess
import sys

log = logging.getLogger(__name__)

FAST, FALLBACK = "llvm_ad_rgb", "scalar_rgb"
_PROBE = (
    "import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
    "s = mi.load_dict({'type': 'scene', 'integrator': {'type': 'path'}, "
    "'sensor': {'type': 'perspective', "
    "'film': {'type': 'hdrfilm', 'width': 4, 'height': 4}}}); mi.render(s, spp=1); print('ok')"
)


def newest_libllvm() -> str | None:
    """Path of the newest installed libLLVM with major version >= 16, or None."""
    found = []
    patterns = ("/usr/lib/*/libLLVM*.so*", "/usr/lib/libLLVM*.so*",
                "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                "/usr/lib64/libLLVM*.so*")
    for path in (p for pattern in patterns for p in glob.glob(pattern)):
        m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
        if m and int(m.group(1)) >= 16:
            found.append((int(m.group(1)), path))
    return max(found)[1] if found else None


@functools.cache
def choose_variant(requested: str = "auto") -> str:
    """Return the Mitsuba variant to use and set it.

    Args:
        requested: ``auto`` (llvm if it works, else scalar), or an explicit variant name.
    """
    import mitsuba as mi

    if requested != "auto":
        if requested not in mi.variants():
            raise ValueError(f"render.variant={requested!r} is not one of {mi.variants()}")
        mi.set_variant(requested)
        return requested
    if "DRJIT_LIBLLVM_PATH" not in os.environ and (lib := newest_libllvm()):
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
    try:
        ok = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                            timeout=120, env=os.environ.copy()).stdout.strip().endswith("ok")
    except subprocess.TimeoutExpired:
        ok = False
    variant = FAST if ok else FALLBACK
    if not ok:
        log.warning("Mitsuba's llvm_ad_rgb variant does not work here (it needs libLLVM >= 16: "
                    "`apt-get install libllvm19`); rendering with scalar_rgb, about 2x slower.")
    mi.set_variant(variant)
    return variant


def shape_index(mi, shape, pos: int) -> int:
    """The value the ``aov`` integrator's ``shape_index`` gives for a shape of a loaded scene.

    Args:
        mi: the mitsuba module (variant set).
        shape: a shape of ``scene.shapes()``.
        pos: its position in ``scene.shapes()``.
    """
    if hasattr(mi, "ShapePtr"):  # JIT variants: the shape's registry id
        import drjit as dr

        return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
    return pos + 1  # scalar: position in scene.shapes(), counted from 1
