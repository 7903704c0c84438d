"""LLVM intrinsics of the closest-point kernels (private): a cache-line prefetch, the walk
step's 8-wide ring (which of a model point's 8 neighbours looks closest to a query), and for
the tree build a many-point nearest update (one candidate against 32 or 8 query points at
once) and an 8-witness test (is a candidate beaten everywhere in a cell?).

All are written in LLVM IR through numba's ``@intrinsic``; they are used by
:mod:`shapeverify.nearest._kernels`, :mod:`shapeverify.nearest._exact_kernels`,
:mod:`shapeverify.nearest._lattice_kernels` and :mod:`shapeverify.nearest._build_kernels`.
The ring is tested bit for bit against a plain numpy evaluation
(``tests/test_query_speedpath.py``), the nearest update against one linear scan per point and
the witness test against the scalar loop (``tests/test_dvg_build.py``).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

RING = 8       # neighbours per model point (``_kernels.K``)


@intrinsic
def prefetch(typingctx, arr, i):
    """Prefetch the cache line of flat element ``i`` of ``arr`` (llvm.prefetch, read, keep)."""
    sig = types.void(arr, i)

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = builder.gep(ary.data, [args[1]])
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0i8")
        builder.call(fn, [builder.bitcast(ptr, i8p), ir.Constant(i32, 0), ir.Constant(i32, 3),
                          ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _ring8(typingctx, rh, i, r0, r1, r2, s):
    """(slot k, value) of the smallest of the 8 values (r0 - s x_k)^2 + (r1 - s y_k)^2 +
    (r2 - s z_k)^2, (x_k, y_k, z_k) = int16 elements ``i + 3k .. i + 3k + 2`` of ``rh`` (flat).

    One 48-byte load, three shuffles, then 8-wide float64 arithmetic in the order of the
    scalar loop ``for k: d = (r0 - s*x)**2 + ...; if d < best: ...`` (no fused or reordered
    operations), so the values and the slot (the first one of the smallest value) are
    bit-identical to it; about a fifth of its instructions.
    """
    if not (isinstance(rh, types.Array) and rh.dtype == types.int16):
        return None
    sig = types.Tuple((types.int64, types.float64))(rh, i, r0, r1, r2, s)

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        i16, i32, i64, f64 = ir.IntType(16), ir.IntType(32), ir.IntType(64), ir.DoubleType()
        v24 = ir.VectorType(i16, 3 * RING)
        ptr = builder.bitcast(builder.gep(ary.data, [args[1]]), v24.as_pointer())
        raw = builder.load(ptr, align=2)
        vd = ir.VectorType(f64, RING)

        def splat(x):
            v = builder.insert_element(ir.Constant(vd, ir.Undefined), x, ir.Constant(i32, 0))
            return builder.shuffle_vector(v, ir.Constant(vd, ir.Undefined),
                                          ir.Constant(ir.VectorType(i32, RING), [0] * RING))

        sv = splat(args[5])
        d = None
        for c in range(3):
            lane = builder.shuffle_vector(raw, ir.Constant(v24, ir.Undefined),
                                          ir.Constant(ir.VectorType(i32, RING),
                                                      [3 * k + c for k in range(RING)]))
            o = builder.sitofp(lane, vd)
            e = builder.fsub(splat(args[2 + c]), builder.fmul(sv, o))
            e2 = builder.fmul(e, e)
            d = e2 if d is None else builder.fadd(d, e2)
        # smallest value: a tree of compare + select (no NaN: finite coordinates)
        m = d
        width = RING
        while width > 1:
            width //= 2
            hi = builder.shuffle_vector(m, ir.Constant(vd, ir.Undefined),
                                        ir.Constant(ir.VectorType(i32, RING),
                                                    [(k + width) % RING for k in range(RING)]))
            m = builder.select(builder.fcmp_ordered("<", hi, m), hi, m)
        best = builder.extract_element(m, ir.Constant(i32, 0))
        eq = builder.fcmp_ordered("==", d, splat(best))
        bits = builder.bitcast(eq, ir.IntType(RING))
        cttz = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.IntType(RING), [ir.IntType(RING), ir.IntType(1)]),
            f"llvm.cttz.i{RING}")
        k = builder.zext(builder.call(cttz, [bits, ir.Constant(ir.IntType(1), 1)]), i64)
        return context.make_tuple(builder, signature.return_type, [k, best])

    return sig, codegen


def _nearest_update(width):
    """An intrinsic ``f(st, x, y, z, j)`` that offers candidate j at (x, y, z) to ``width``
    query points at once.  ``st`` (5 width,) float64, C-contiguous: the query points' x, y, z
    (a width-block each), then the best squared distances and the best indices (as float64).
    The squared distance ``((x - qx)^2 + (y - qy)^2) + (z - qz)^2`` is formed in that order
    (no fused or reordered operations: bit for bit a scalar search's), and the candidate
    replaces the best when it is closer, or as close with a lower index (a linear scan's
    tie rule in any candidate order)."""

    @intrinsic
    def update(typingctx, st, x, y, z, j):
        if not (isinstance(st, types.Array) and st.dtype == types.float64):
            return None
        sig = types.void(st, x, y, z, j)

        def codegen(context, builder, signature, args):
            ary = context.make_array(signature.args[0])(context, builder, args[0])
            f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
            vd = ir.VectorType(f64, width)

            def block(k):
                return builder.bitcast(builder.gep(ary.data, [ir.Constant(i64, k * width)]),
                                       vd.as_pointer())

            def splat(v):
                e = builder.insert_element(ir.Constant(vd, ir.Undefined), v, ir.Constant(i32, 0))
                return builder.shuffle_vector(e, ir.Constant(vd, ir.Undefined),
                                              ir.Constant(ir.VectorType(i32, width), [0] * width))

            d = None
            for c in range(3):
                e = builder.fsub(splat(args[1 + c]), builder.load(block(c), align=8))
                e2 = builder.fmul(e, e)
                d = e2 if d is None else builder.fadd(d, e2)
            bd = builder.load(block(3), align=8)
            bi = builder.load(block(4), align=8)
            sj = splat(args[4])
            take = builder.or_(builder.fcmp_ordered("<", d, bd),
                               builder.and_(builder.fcmp_ordered("==", d, bd),
                                            builder.fcmp_ordered("<", sj, bi)))
            builder.store(builder.select(take, d, bd), block(3), align=8)
            builder.store(builder.select(take, sj, bi), block(4), align=8)
            return context.get_dummy_value()

        return sig, codegen

    return update


nearest_update32 = _nearest_update(32)
nearest_update8 = _nearest_update(8)


@intrinsic
def beaten8(typingctx, w, x0, x1, x2, dp, h2, p):
    """Whether one of 8 witnesses beats point p (at x, squared distance ``dp`` to a cube's
    centre) everywhere in the cube: ``(da - dp) + h2 * ((|x0 - y0| + |x1 - y1|) + |x2 - y2|)
    < -1e-9 * (da + dp)`` for a witness y (squared distance da to the centre) that is not p
    itself, evaluated in that order for the 8 at once (bit for bit the scalar test).
    ``w`` (40,) float64, C-contiguous: the witnesses' y0, y1, y2, da and indices (float64),
    8 each."""
    if not (isinstance(w, types.Array) and w.dtype == types.float64):
        return None
    sig = types.boolean(w, x0, x1, x2, dp, h2, p)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
        vd = ir.VectorType(f64, RING)

        def block(k):
            return builder.load(builder.bitcast(
                builder.gep(ary.data, [ir.Constant(i64, k * RING)]), vd.as_pointer()), align=8)

        def splat(v):
            e = builder.insert_element(ir.Constant(vd, ir.Undefined), v, ir.Constant(i32, 0))
            return builder.shuffle_vector(e, ir.Constant(vd, ir.Undefined),
                                          ir.Constant(ir.VectorType(i32, RING), [0] * RING))

        fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vd, [vd]),
                                              f"llvm.fabs.v{RING}f64")
        s = None
        for c in range(3):
            a = builder.call(fabs, [builder.fsub(splat(args[1 + c]), block(c))])
            s = a if s is None else builder.fadd(s, a)
        da = block(3)
        dpv = splat(args[4])
        worst = builder.fadd(builder.fsub(da, dpv), builder.fmul(splat(args[5]), s))
        thr = builder.fmul(ir.Constant(vd, [-1e-9] * RING), builder.fadd(da, dpv))
        beat = builder.and_(builder.fcmp_ordered("<", worst, thr),
                            builder.fcmp_unordered("!=", block(4), splat(args[6])))
        bits = builder.bitcast(beat, ir.IntType(RING))
        return builder.icmp_unsigned("!=", bits, ir.Constant(ir.IntType(RING), 0))

    return sig, codegen


@intrinsic
def kept8(typingctx, xs, ys, zs, ids, s, nv, w, nw, c0, c1, c2, half, uu, h2):
    """Which of 8 candidate points survive a cell's box and witness tests, at once: the bit
    mask (int64) of the lanes l < ``nv`` whose point p (coordinates ``xs[s + l]``, ``ys``,
    ``zs``, index ``ids[s + l]``) is kept, for 8 points what ``_build_kernels._keep`` decides
    for one, bit for bit: p is dropped when ``(g0 g0 + g1 g1) + g2 g2 > uu`` (``g_k =
    max(|x_k - c_k| - half, 0)``), or when one of the first ``nw`` witnesses of ``w``
    (:func:`beaten8`'s layout) that is not p itself has ``(da - dp) + h2 ((|x0 - y0| +
    |x1 - y1|) + |x2 - y2|) < -1e-9 (da + dp)``, ``dp = ((x0 - c0)^2 + (x1 - c1)^2) +
    (x2 - c2)^2``.  ``xs``, ``ys``, ``zs`` float64 and ``ids`` int32 are read 8 elements
    from ``s`` on: they must hold them (padding beyond the candidates)."""
    if not (isinstance(w, types.Array) and w.dtype == types.float64
            and isinstance(ids, types.Array) and ids.dtype == types.int32):
        return None
    sig = types.int64(xs, ys, zs, ids, s, nv, w, nw, c0, c1, c2, half, uu, h2)

    def codegen(context, builder, signature, args):
        f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
        vd = ir.VectorType(f64, RING)
        vi = ir.VectorType(i32, RING)
        args = list(args)
        for k in range(4, 14):
            if k != 6:
                to = types.int64 if k in (4, 5, 7) else types.float64
                args[k] = context.cast(builder, args[k], signature.args[k], to)

        def splat(v, vt=vd):
            e = builder.insert_element(ir.Constant(vt, ir.Undefined), v, ir.Constant(i32, 0))
            return builder.shuffle_vector(e, ir.Constant(vt, ir.Undefined),
                                          ir.Constant(ir.VectorType(i32, RING), [0] * RING))

        def lanes(k, vt):
            ary = context.make_array(signature.args[k])(context, builder, args[k])
            ptr = builder.gep(ary.data, [args[4]])
            return builder.load(builder.bitcast(ptr, vt.as_pointer()), align=4)

        x = [lanes(k, vd) for k in range(3)]
        pid = builder.sitofp(lanes(3, vi), vd)
        wary = context.make_array(signature.args[6])(context, builder, args[6])
        fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vd, [vd]),
                                              f"llvm.fabs.v{RING}f64")
        zero = ir.Constant(vd, [0.0] * RING)
        gg = dp = None
        for k in range(3):
            e = builder.fsub(x[k], splat(args[8 + k]))
            a = builder.fsub(builder.call(fabs, [e]), splat(args[11]))
            g = builder.select(builder.fcmp_ordered(">", a, zero), a, zero)
            g2 = builder.fmul(g, g)
            e2 = builder.fmul(e, e)
            gg = g2 if gg is None else builder.fadd(gg, g2)
            dp = e2 if dp is None else builder.fadd(dp, e2)
        # dropped lanes: beyond nv, outside the box bound, then beaten by a witness
        lane_no = ir.Constant(vi, list(range(RING)))
        nvv = splat(builder.trunc(args[5], i32), vi)
        drop = builder.or_(builder.icmp_signed(">=", lane_no, nvv),
                           builder.fcmp_ordered(">", gg, splat(args[12])))
        acc = cgutils.alloca_once_value(builder, drop)
        h2v = splat(args[13])
        with cgutils.for_range(builder, args[7]) as loop:
            def wit(k):
                idx = builder.add(ir.Constant(i64, k * RING), loop.index)
                return splat(builder.load(builder.gep(wary.data, [idx])))
            s = None
            for k in range(3):
                a = builder.call(fabs, [builder.fsub(x[k], wit(k))])
                s = a if s is None else builder.fadd(s, a)
            da = wit(3)
            worst = builder.fadd(builder.fsub(da, dp), builder.fmul(h2v, s))
            thr = builder.fmul(ir.Constant(vd, [-1e-9] * RING), builder.fadd(da, dp))
            beat = builder.and_(builder.fcmp_ordered("<", worst, thr),
                                builder.fcmp_unordered("!=", pid, wit(4)))
            builder.store(builder.or_(builder.load(acc), beat), acc)
        keep = builder.not_(builder.load(acc))
        return builder.zext(builder.bitcast(keep, ir.IntType(RING)), i64)

    return sig, codegen
