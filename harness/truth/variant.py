"""Which Mitsuba variant the reference loads, chosen without loading one that would abort the
process (Dr.Jit's LLVM backend aborts, uncatchably, with LLVM 15 or older)."""

from __future__ import annotations

import glob
import os
import re
import warnings

LLVM_SEARCH = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
               "/usr/lib", "/usr/local/lib")


def _llvm_libraries() -> list[tuple[int, str]]:
    found = []
    for folder in LLVM_SEARCH:
        for path in glob.glob(os.path.join(folder, "libLLVM*.so*")):
            m = re.search(r"libLLVM-?(\d+)", os.path.basename(path))
            if m:
                found.append((int(m.group(1)), path))
    return sorted(found, reverse=True)


def choose_variant() -> str:
    """Pick a Mitsuba variant without loading one that would abort the process.

    ``cuda_ad_rgb`` when Dr.Jit finds a CUDA device; else ``llvm_ad_rgb`` when an LLVM >= 16
    library exists (Dr.Jit's LLVM backend aborts, uncatchably, with LLVM 15 or older), and
    Dr.Jit is pointed at it; else ``scalar_rgb`` with a warning.
    ``$SHADOWBENCH_MITSUBA_VARIANT`` forces a variant.
    """
    import drjit as dr
    import mitsuba as mi

    forced = os.environ.get("SHADOWBENCH_MITSUBA_VARIANT")
    if forced:
        return forced
    if "cuda_ad_rgb" in mi.variants() and dr.has_backend(dr.JitBackend.CUDA):
        return "cuda_ad_rgb"
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    libraries = _llvm_libraries()
    if not chosen and libraries and libraries[0][0] >= 16:
        os.environ["DRJIT_LIBLLVM_PATH"] = chosen = libraries[0][1]
    version = next((v for v, p in libraries if p == chosen), None)
    if chosen and (version is None or version >= 16) and "llvm_ad_rgb" in mi.variants():
        return "llvm_ad_rgb"
    warnings.warn(
        "no LLVM >= 16 found (Debian: apt-get install libllvm19); the reference falls back to "
        "Mitsuba's scalar_rgb variant, which is much slower", RuntimeWarning, stacklevel=2)
    return "scalar_rgb"


def mitsuba_module(variant: str):
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi
