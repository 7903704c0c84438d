"""Array views that numba's reference counting skips (private; for the hot kernels).

Every array passed into a numba callee otherwise costs two atomic operations per call; in the
per-point path of the exact closest point that was as much as a surface evaluation.
"""

from __future__ import annotations

from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def _borrow(typingctx, arr):
    """A view of ``arr`` without its memory-info pointer, which numba's reference counting
    skips (NRT_incref / NRT_decref return at once on a null pointer).

    Only for arrays that outlive every use of the view: here the arguments of a kernel,
    which the caller holds for the whole call.  The view must not be returned or stored.
    """
    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        dst = context.make_array(signature.return_type)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(dst, name, getattr(src, name))
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        return dst._getvalue()

    return arr(arr), codegen
