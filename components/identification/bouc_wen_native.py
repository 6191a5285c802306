"""Bouc-Wen state along displacement paths for a whole FFOA population, in C or in numpy.

:func:`path_states` gives what :func:`components.physics.bouc_wen_core.bouc_wen_states`
gives for a batch of parameter sets (the same scheme, the same batch-wide sub-step
counts), with the per-sample loop in C (``native/bouc_wen_kernel.c``), vectorised over the
parameter sets. The numpy loop pays numpy's per-call overhead (about a microsecond) some
40 times per sub-step, whatever the batch size, which made Bouc-Wen FFOA cost minutes.

The kernel is compiled with the system C compiler (``$CC``, default ``cc``) on first use
into a cache folder (``$MRE_COSIM_CACHE``, default ``~/.cache/mre-cosim``), as the master's
native executor is, and reused while its source is unchanged: first the SIMD build (glibc's
libmvec), else the plain C one. Without either (no compiler), or with
``MRE_COSIM_BOUC_WEN=numpy`` in the environment, the numpy loop runs instead (exactly
``bouc_wen_core``'s, tested bit for bit). C and numpy do the same floating-point operations
in the same order; they can differ in the last bits of ``pow`` and ``expm1`` (numpy uses its
own SIMD versions on some CPUs), see tests/physics/test_bouc_wen.py. Units: any consistent length
unit for x, dx_max and 1/beta, 1/gamma, 1/delta (identification: mm); y is dimensionless.
"""

from __future__ import annotations

import ctypes
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from components.physics.bouc_wen_core import bouc_wen_step, envelope, envelope_rate
from mre_common import c_compile

SOURCE = Path(__file__).resolve().parent / "native" / "bouc_wen_kernel.c"
CFLAGS = ("-shared", "-fPIC", "-O2", "-ffp-contract=off", "-fno-math-errno", "-fno-trapping-math", "-std=c99",
          "-Wall", "-Wextra", "-Wno-unknown-pragmas")
# Builds tried in order: vectorised over the parameter sets with glibc's vector math library
# (libmvec, glibc >= 2.35), then plain C. -fno-math-errno and -fno-trapping-math change no
# result (errno and floating-point traps are not used); they let the compiler vectorise.
VARIANTS: dict[str, tuple[str, ...]] = {
    "c-simd": ("-DBW_LIBMVEC", "-fopenmp-simd", "-Wl,--no-undefined", "-lmvec", "-lm"),
    "c": ("-lm",),
}
# Parameter sets per SIMD vector a build may use (AVX-512: 8 doubles); batches are padded to it.
LANES: dict[str, int] = {"c-simd": 8, "c": 1}
ENV_BACKEND = "MRE_COSIM_BOUC_WEN"  # "numpy" forces the numpy path, "c" the plain C build

_LIBRARIES: dict[str, Any] = {}  # build -> loaded library
_FAILED: dict[str, str] = {}  # build -> why it cannot be had


def _load(variant: str) -> Any:
    """Compile (once per source, compiler and flags) and load one build; OSError if impossible."""
    try:
        target = c_compile.compile_cached(SOURCE, CFLAGS, VARIANTS[variant], name=f"bouc_wen_kernel-{variant}")
    except c_compile.CompileFailed as exc:
        raise OSError(f"compiling {SOURCE.name} with {exc.compiler!r} failed: {exc.stderr.strip()[:300]}") from None
    library = ctypes.CDLL(str(target))
    p, i64, f64 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
    library.bouc_wen_states.argtypes = [i64, i64, i64, p, p, p, p, p, p, f64, f64, p, p]
    library.bouc_wen_states.restype = None
    return library


def _get(variant: str) -> Any | None:
    if variant not in VARIANTS:
        return None
    if variant not in _LIBRARIES and variant not in _FAILED:
        try:
            _LIBRARIES[variant] = _load(variant)
        except OSError as exc:  # no compiler, no libmvec, an unwritable cache folder
            _FAILED[variant] = str(exc)
    return _LIBRARIES.get(variant)


def _default_variant() -> str | None:
    wanted = os.environ.get(ENV_BACKEND, "").lower()
    if wanted == "numpy":
        return None
    for variant in VARIANTS if wanted not in VARIANTS else (wanted,):
        if _get(variant) is not None:
            return variant
    return None


def kernel(variant: str | None = None) -> Any | None:
    """A compiled build of the kernel (default: the first of :data:`VARIANTS` that works,
    unless ``$MRE_COSIM_BOUC_WEN`` says otherwise), or None if it cannot be had."""
    variant = variant or _default_variant()
    return None if variant is None else _get(variant)


def unavailable_reason(variant: str | None = None) -> str | None:
    """Why a build (default: any) is not used, or None if it is."""
    if variant is None:
        if os.environ.get(ENV_BACKEND, "").lower() == "numpy":
            return f"{ENV_BACKEND}=numpy"
        if _default_variant() is not None:
            return None
        return "; ".join(f"{v}: {why}" for v, why in _FAILED.items())
    if variant not in VARIANTS:
        return f"unknown build {variant!r} (known: {', '.join(VARIANTS)})"
    _get(variant)
    return _FAILED.get(variant)


def backend() -> str:
    """What :func:`path_states` uses by default: a build of :data:`VARIANTS` or "numpy"."""
    return _default_variant() or "numpy"


def substep_counts(adx: np.ndarray, lam_max: float, dx_max: float, lam_dx_max: float, cap: int) -> np.ndarray:
    """:func:`bouc_wen_core.substeps` for every sample at once; adx = largest |dx| per sample [length]."""
    adx = np.asarray(adx, dtype=float)
    with np.errstate(invalid="ignore"):  # 0 * inf where adx = 0 (those samples take 1 sub-step)
        lam_term = adx * lam_max / lam_dx_max if math.isfinite(lam_dx_max) else np.zeros_like(adx)
        m = np.maximum(np.maximum(adx / dx_max, lam_term), 1.0)
        counts = np.where(m >= cap, cap, np.ceil(np.minimum(m, cap)))
    return np.where(adx == 0.0, 1, counts).astype(np.int64)


def _numpy_states(dx: np.ndarray, m: np.ndarray, b, g, delta: float, e, bound) -> np.ndarray:
    """The loop of ``bouc_wen_core.bouc_wen_states`` with a given sub-step schedule (numpy path)."""
    y = np.zeros(np.broadcast_shapes(dx.shape[:-1], np.shape(b)))
    out = np.empty((*y.shape, dx.shape[-1] + 1))
    out[..., 0] = y
    for k in range(dx.shape[-1]):
        h = dx[..., k] / int(m[k])
        for _ in range(int(m[k])):
            y = np.clip(bouc_wen_step(y, h, b, g, delta, e), -bound, bound)
        out[..., k + 1] = y
    return out


def path_states(  # noqa: PLR0913 - the law's parameter arrays and the integrator's limits, per call of a hot kernel
    x: np.ndarray,
    beta,
    gamma,
    delta: float,
    n,
    dx_max: float,
    lam_dx_max: float = 0.5,
    cap: int = 64,
    use: str | None = None,
    lam_max: float | None = None,
) -> np.ndarray:
    """Bouc-Wen state y [1] at every sample of the paths x (N,) or (R, N), from y = 0.

    beta, gamma, n: scalars or 1-D arrays of P parameter sets (consistent units with x,
    delta and dx_max, e.g. mm and 1/mm); delta a scalar. Result (P, R, N), without the P
    axis for scalar parameters and without the R axis for a 1-D x; equal to
    ``bouc_wen_states(x, beta[:, None], gamma[:, None], delta, n[:, None], ...)``: the
    sub-step count of a sample is the largest over the batch (:func:`bouc_wen_core.substeps`
    with Lam = ``lam_max``, default the batch's :func:`bouc_wen_core.envelope_rate`; pass a
    population's Lam to compute one of its members alone). ``use``: a build of
    :data:`VARIANTS`, "numpy", or None (the first build available, else numpy).
    """
    x = np.asarray(x, dtype=float)
    scalar = all(np.ndim(a) == 0 for a in (beta, gamma, n))
    b, g, e = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=float)) for a in (beta, gamma, n)))
    if b.ndim != 1 or np.ndim(delta) != 0 or x.ndim not in (1, 2) or x.shape[-1] < 1:
        raise ValueError("path_states: parameters must be scalars or 1-D, delta a scalar, x of shape (N,) or (R, N)")
    paths = np.atleast_2d(x)
    dx = np.diff(paths, axis=-1)
    with np.errstate(all="ignore"):
        if lam_max is None:
            lam_max = envelope_rate(b, g, delta, e)
        bound = np.broadcast_to(envelope(b, g, delta, e), b.shape)
        m = substep_counts(np.max(np.abs(dx), axis=0, initial=0.0), lam_max, dx_max, lam_dx_max, cap)
    variant = None if use == "numpy" else (use or _default_variant())
    library = None if variant is None else _get(variant)
    if library is None:
        if variant is not None:
            raise RuntimeError(f"path_states: build {variant!r} not available ({unavailable_reason(variant)})")
        col = (slice(None), None) if x.ndim == 2 else (slice(None),)
        with np.errstate(all="ignore"):
            out = _numpy_states(dx if x.ndim == 2 else dx[0], m, b[col], g[col], float(delta), e[col], bound[col])
    else:
        # pad the batch (repeating its last set) to whole SIMD vectors: every set then goes
        # through the same vector code, so its result does not depend on the batch
        sets = b.size
        size = -(-sets // LANES[variant]) * LANES[variant]
        b, g, e, bound = (np.ascontiguousarray(np.pad(a, (0, size - sets), mode="edge"), dtype=float)
                          for a in (b, g, e, bound))
        dx, m = np.ascontiguousarray(dx), np.ascontiguousarray(m)
        out = np.empty((size, *paths.shape))
        work = np.empty(size)
        library.bouc_wen_states(size, paths.shape[0], paths.shape[1], dx.ctypes.data, m.ctypes.data,
                                b.ctypes.data, g.ctypes.data, e.ctypes.data, bound.ctypes.data, float(delta), 0.0,
                                work.ctypes.data, out.ctypes.data)
        out = out[:sets, 0] if x.ndim == 1 else out[:sets]
    return out[0] if scalar else out
