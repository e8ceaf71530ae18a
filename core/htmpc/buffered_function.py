"""A casadi `Function` evaluated in place on numpy buffers, optionally compiled with gcc (casadi's JIT).

A plain call spends most of its time converting the `DM` result to numpy; compiled and called through
casadi's `Function.buffer()` on preallocated numpy arrays the same evaluation is an order of magnitude
cheaper (docs/decisions.md, "Kinematics over the horizon in one compiled call"). Kinematics only: the
HPIPM-backed QP is called normally (a buffered `conic` returned wrong points flagged as successes).
"""

from __future__ import annotations

import logging
import shutil
import tempfile

import casadi as ca
import numpy as np

log = logging.getLogger(__name__)


def compiled(fn: ca.Function, jit: bool = True) -> ca.Function:
    """An SX function JIT-compiled with gcc when `jit` and gcc is installed, else `fn` itself."""
    if not jit or shutil.which("gcc") is None:
        return fn
    opts = {"jit": True, "compiler": "shell",
            "jit_options": {"flags": ["-O2"], "verbose": False, "directory": tempfile.gettempdir() + "/"}}
    try:
        args = fn.sx_in()
        out = ca.Function(f"{fn.name()}_jit", args, fn.call(args), opts)
        out.call([np.zeros(fn.size_in(i)) for i in range(fn.n_in())])  # compile now, not on the first solve
        return out
    except RuntimeError as err:  # no working compiler: the interpreted function is correct, only slower
        log.warning("casadi JIT failed, using the interpreted %s: %s", fn.name(), err)
        return fn


class BufferedFunction:
    """Calls a casadi Function on preallocated dense numpy buffers (inputs and outputs as non-zeros).

    `inputs[i]` and `outputs[i]` are flat float arrays of `nnz_in(i)` / `nnz_out(i)` entries in casadi's
    column-major non-zero order; write the inputs, call `evaluate()`, read (copy) the outputs.
    """

    def __init__(self, fn: ca.Function) -> None:
        self.fn = fn
        self._buffer, self._trigger = fn.buffer()
        self.inputs = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.outputs = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        # casadi's SWIG signatures also list the buffer's size, which its typemap takes from the memoryview
        for i, a in enumerate(self.inputs):
            self._buffer.set_arg(i, memoryview(a))  # pyright: ignore[reportCallIssue, reportArgumentType]
        for i, a in enumerate(self.outputs):
            self._buffer.set_res(i, memoryview(a))  # pyright: ignore[reportCallIssue, reportArgumentType]

    def evaluate(self) -> int:
        """Run the function on the current inputs; returns casadi's return flag (0 = fine)."""
        self._trigger()
        return int(self._buffer.ret())

    def stats(self) -> dict:
        """casadi's statistics of the last evaluation (for a solver: `success`, `iter_count`, ...)."""
        return self._buffer.stats()
