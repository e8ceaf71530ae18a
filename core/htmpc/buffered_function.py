"""A casadi `Function` evaluated in place on numpy buffers, optionally compiled with gcc (casadi's JIT).

A plain call spends most of its time converting numpy to `DM` and back (casadi converts element by element);
called through casadi's `Function.buffer()` on preallocated numpy arrays the same evaluation is an order of
magnitude cheaper (docs/decisions.md, "Kinematics over the horizon in one compiled call", "The QP through a
re-bound buffer"). A solver (`conic`) needs `rebind=True`: its evaluation replaces the argument pointers it
was given, so without re-binding every call after the first solved with stale data.
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

    def __init__(self, fn: ca.Function, rebind: bool = False) -> None:
        self.fn = fn
        self.rebind = rebind
        """Bind the buffers again before every call: needed for a casadi solver (`conic`), whose evaluation
        overwrites the bound argument pointers (casadi 3.8 with HPIPM: every call after the first returned
        wrong points flagged as successes; re-bound, 168 of 168 closed-loop QPs equalled the `DM` call bit for
        bit)."""
        self._buffer, self._trigger = fn.buffer()
        self.inputs = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.outputs = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        self._views = ([a.data for a in self.inputs], [a.data for a in self.outputs])
        self._bind()

    def _bind(self) -> None:
        # casadi's SWIG signatures also list the buffer's size, which its typemap takes from the memoryview
        ins, outs = self._views
        for i, view in enumerate(ins):
            self._buffer.set_arg(i, view)  # pyright: ignore[reportCallIssue, reportArgumentType]
        for i, view in enumerate(outs):
            self._buffer.set_res(i, view)  # pyright: ignore[reportCallIssue, reportArgumentType]

    def evaluate(self) -> int:
        """Run the function on the current inputs; returns casadi's return flag (0 = fine)."""
        if self.rebind:
            self._bind()
        self._trigger()
        return int(self._buffer.ret())

    def stats(self) -> dict:
        """casadi's statistics of the last evaluation (for a solver: `success`, `iter_count`, ...)."""
        return self._buffer.stats()
