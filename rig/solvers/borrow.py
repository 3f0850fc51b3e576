"""Arrays without reference counting inside compiled code.

numba counts references to every array a compiled function passes on or slices (an atomic increment and
decrement per call of a kernel that takes the parameter vector, per row view of a stage matrix): on a
right-hand side of a few hundred nanoseconds that is a fifth of the time. :func:`borrowed` gives a view of an
array with no reference count (a NULL meminfo, on which numba's increments and decrements are no-ops); views of
it are borrowed too. Valid only while the original array lives — the compiled solvers borrow their arguments
for the duration of one call.
"""
from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def borrowed(typingctx, arr):
    """``arr`` viewed without a reference count (same data, shape and strides)."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, sig, args):
        src = context.make_array(sig.args[0])(context, builder, args[0])
        dst = context.make_array(sig.return_type)(context, builder)
        for name in ("parent", "nitems", "itemsize", "data", "shape", "strides"):
            setattr(dst, name, getattr(src, name))
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        return dst._getvalue()

    return arr(arr), codegen
