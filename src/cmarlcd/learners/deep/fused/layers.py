"""The building blocks of the fused CPU step (:mod:`cmarlcd.learners.deep.fused.kernels`):
dense and one-hot layers with their gradients, and Adam, compiled with numba.

Every array a layer reads or writes is *feature-major*: ``(units, N)``, each row running
over the batch's N transitions, so that the inner loops are long and contiguous and the
compiler vectorises them. The layers take register blocks (several outputs and inputs per
pass over the batch), as a matrix-product kernel does.
"""

from __future__ import annotations

import contextlib
import hashlib
from pathlib import Path

import numpy as np
from numba import njit

#: Floating-point liberties the kernels take: reorder and fuse sums (vectorised
#: reductions), never assume finite values.
FASTMATH = {"contract", "reassoc", "nsz", "arcp"}


def drop_stale_caches(directory: Path) -> bool:
    """Delete the on-disk caches of the fused kernels in ``directory`` when any of its
    ``*.py`` sources changed since they were written; True if it deleted them.

    Numba checks a cached function against its own file only, so a kernel whose callee
    lives in another module (``td_step`` calls ``mixers.mix``) would keep running
    the old callee after that module changed. The fused modules are one unit here: a
    stamp of all their sources guards every one's cache. (Caches placed elsewhere by
    ``NUMBA_CACHE_DIR`` are not covered.)"""
    sources = sorted(directory.glob("*.py"))
    stamp = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()
    cache = directory / "__pycache__"
    marker = cache / "fused-sources.stamp"
    with contextlib.suppress(OSError):
        if marker.read_text() == stamp:
            return False
    with contextlib.suppress(OSError):  # a read-only install: numba caches elsewhere
        for stale in cache.glob("*.nb[ic]"):
            stale.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        marker.write_text(stamp)
    return True


drop_stale_caches(Path(__file__).parent)


def fused(function):
    """Compile ``function`` for the fused step (cached on disk, see :data:`FASTMATH`).

    ``error_model="numpy"``: a float division is IEEE's (no zero test raising Python's
    ZeroDivisionError). The test is a branch in the loop, and a loop with it is not
    vectorised: Adam ran 6x slower with it. No kernel divides by a value that can be 0."""
    return njit(cache=True, fastmath=FASTMATH, nogil=True, error_model="numpy")(function)


def inlined(function):
    """Compile a small helper of the kernels into every kernel that calls it (numba's
    own inlining): a call left to LLVM is not always inlined, and a call per element
    keeps a loop from being vectorised (ELU ran 8x slower behind one)."""
    return njit(inline="always", fastmath=FASTMATH, error_model="numpy")(function)


# ------------------------------------------------------------------ dense layers


@fused
def dense_forward(w, b, x, out) -> None:
    """``out`` (O, N) := ``wᵀ x + b`` for ``x`` (I, N), ``w`` (I, O), ``b`` (O,).

    Four outputs by four inputs at a time: each pass over the batch loads four input
    rows once for sixteen products (a register block, as a matrix-product kernel has)."""
    inputs, count = x.shape
    o = 0
    while o + 4 <= w.shape[1]:
        r0, r1, r2, r3 = out[o], out[o + 1], out[o + 2], out[o + 3]
        c0, c1, c2, c3 = b[o], b[o + 1], b[o + 2], b[o + 3]
        for t in range(count):
            r0[t], r1[t], r2[t], r3[t] = c0, c1, c2, c3
        k = 0
        while k + 4 <= inputs:
            x0, x1, x2, x3 = x[k], x[k + 1], x[k + 2], x[k + 3]
            a0, a1, a2, a3 = w[k, o], w[k + 1, o], w[k + 2, o], w[k + 3, o]
            b0, b1, b2, b3 = w[k, o + 1], w[k + 1, o + 1], w[k + 2, o + 1], w[k + 3, o + 1]
            d0, d1, d2, d3 = w[k, o + 2], w[k + 1, o + 2], w[k + 2, o + 2], w[k + 3, o + 2]
            e0, e1, e2, e3 = w[k, o + 3], w[k + 1, o + 3], w[k + 2, o + 3], w[k + 3, o + 3]
            for t in range(count):
                p, q, r, s = x0[t], x1[t], x2[t], x3[t]
                r0[t] += a0 * p + a1 * q + a2 * r + a3 * s
                r1[t] += b0 * p + b1 * q + b2 * r + b3 * s
                r2[t] += d0 * p + d1 * q + d2 * r + d3 * s
                r3[t] += e0 * p + e1 * q + e2 * r + e3 * s
            k += 4
        while k < inputs:
            xk = x[k]
            a0, b0, d0, e0 = w[k, o], w[k, o + 1], w[k, o + 2], w[k, o + 3]
            for t in range(count):
                p = xk[t]
                r0[t] += a0 * p
                r1[t] += b0 * p
                r2[t] += d0 * p
                r3[t] += e0 * p
            k += 1
        o += 4
    while o < w.shape[1]:  # the last outputs one at a time, still four inputs a pass
        row, bias = out[o], b[o]
        for t in range(count):
            row[t] = bias
        k = 0
        while k + 4 <= inputs:
            x0, x1, x2, x3 = x[k], x[k + 1], x[k + 2], x[k + 3]
            a0, a1, a2, a3 = w[k, o], w[k + 1, o], w[k + 2, o], w[k + 3, o]
            for t in range(count):
                row[t] += a0 * x0[t] + a1 * x1[t] + a2 * x2[t] + a3 * x3[t]
            k += 4
        while k < inputs:
            wk, xk = w[k, o], x[k]
            for t in range(count):
                row[t] += wk * xk[t]
            k += 1
        o += 1


@fused
def dense_backward(x, grad_out, grad_w, grad_b) -> None:
    """``grad_w`` (I, O) += ``x grad_outᵀ``, ``grad_b`` (O,) += the rows' sums.

    Four inputs by two outputs at a time: eight sums share each pass over the batch."""
    inputs, count = x.shape
    for o in range(grad_out.shape[0]):
        d, total = grad_out[o], np.float32(0.0)
        for t in range(count):
            total += d[t]
        grad_b[o] += total
    o = 0
    while o + 2 <= grad_out.shape[0]:
        d0, d1 = grad_out[o], grad_out[o + 1]
        k = 0
        while k + 4 <= inputs:
            x0, x1, x2, x3 = x[k], x[k + 1], x[k + 2], x[k + 3]
            s00 = s10 = s20 = s30 = s01 = s11 = s21 = s31 = np.float32(0.0)
            for t in range(count):
                p, q = d0[t], d1[t]
                s00 += x0[t] * p
                s10 += x1[t] * p
                s20 += x2[t] * p
                s30 += x3[t] * p
                s01 += x0[t] * q
                s11 += x1[t] * q
                s21 += x2[t] * q
                s31 += x3[t] * q
            grad_w[k, o] += s00
            grad_w[k + 1, o] += s10
            grad_w[k + 2, o] += s20
            grad_w[k + 3, o] += s30
            grad_w[k, o + 1] += s01
            grad_w[k + 1, o + 1] += s11
            grad_w[k + 2, o + 1] += s21
            grad_w[k + 3, o + 1] += s31
            k += 4
        while k < inputs:
            xk, s0, s1 = x[k], np.float32(0.0), np.float32(0.0)
            for t in range(count):
                s0 += xk[t] * d0[t]
                s1 += xk[t] * d1[t]
            grad_w[k, o] += s0
            grad_w[k, o + 1] += s1
            k += 1
        o += 2
    if o < grad_out.shape[0]:
        d = grad_out[o]
        for k in range(inputs):
            xk, total = x[k], np.float32(0.0)
            for t in range(count):
                total += xk[t] * d[t]
            grad_w[k, o] += total


@fused
def relu_inplace(z) -> None:
    for h in range(z.shape[0]):
        row = z[h]
        for t in range(z.shape[1]):
            if not row[t] > 0.0:
                row[t] = 0.0


@fused
def transpose_into(x, out) -> None:
    """``out`` (F, N) := ``x`` (N, F)ᵀ."""
    for t in range(x.shape[0]):
        for f in range(x.shape[1]):
            out[f, t] = x[t, f]


# ------------------------------------------------------------------ Adam


@fused
def adam(param, grad, first, second, lo: int, hi: int, lr: float, settings) -> None:
    """One Adam step on ``param[lo:hi]`` (flat), as PyTorch's (no weight decay, no
    amsgrad); ``settings``: (step, beta1, beta2, eps)."""
    step, beta1, beta2, eps = settings
    step_size = np.float32(lr / (1.0 - beta1**step))
    root = np.float32(np.sqrt(1.0 - beta2**step))
    b1, b2, epsilon = np.float32(beta1), np.float32(beta2), np.float32(eps)
    # slices, so that the loop's index is known to be >= 0 (no negative-index test in it)
    p, g, m, v = param[lo:hi], grad[lo:hi], first[lo:hi], second[lo:hi]
    for j in range(p.shape[0]):
        m[j] += (np.float32(1.0) - b1) * (g[j] - m[j])
        v[j] = b2 * v[j] + (np.float32(1.0) - b2) * g[j] * g[j]
        p[j] -= step_size * m[j] / (np.sqrt(v[j]) / root + epsilon)


@fused
def update_seed(optimiser, b: int, seeds: int) -> None:
    """Adam on seed ``b``'s rows of every parameter (a seed's parameters are a contiguous
    block of each flat array: seeds are the arrays' leading groups), while its gradients
    are still in cache. ``optimiser``: the flat parameters, their gradients, Adam's two
    moments, each parameter's learning rate and (step, beta1, beta2, eps)."""
    params, grads, first, second, rates, settings = optimiser
    for k in range(len(params)):
        size = params[k].shape[0] // seeds
        lo, hi = b * size, (b + 1) * size
        adam(params[k], grads[k], first[k], second[k], lo, hi, rates[k], settings)


@fused
def clip_seed(grads, b: int, seeds: int, max_norm: float) -> None:
    """Scale seed ``b``'s rows of every gradient so that their joint L2 norm is at most
    ``max_norm``: by ``max_norm / (norm + 1e-6)`` where that is below 1, the rule of
    ``torch.nn.utils.clip_grad_norm_`` (and of
    :func:`cmarlcd.learners.deep.td_options.clip_per_seed`); the squares are
    summed in float64."""
    total = 0.0
    for k in range(len(grads)):
        size = grads[k].shape[0] // seeds
        g = grads[k][b * size : (b + 1) * size]
        for j in range(g.shape[0]):
            total += np.float64(g[j]) * np.float64(g[j])
    scale = max_norm / (np.sqrt(total) + 1e-6)
    if scale < 1.0:
        factor = np.float32(scale)
        for k in range(len(grads)):
            size = grads[k].shape[0] // seeds
            g = grads[k][b * size : (b + 1) * size]
            for j in range(g.shape[0]):
                g[j] *= factor


@fused
def zero_seed(grads, b: int, seeds: int) -> None:
    for k in range(len(grads)):
        size = grads[k].shape[0] // seeds
        grads[k][b * size : (b + 1) * size] = 0.0
