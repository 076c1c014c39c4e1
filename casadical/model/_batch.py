"""A mapped CasADi Function evaluated in place on numpy buffers, whole or in blocks on threads."""

from __future__ import annotations

from concurrent.futures import wait

import casadi as ca
import numpy as np

from ..runtime._threads import evaluation_pool, evaluation_threads

#: a batch on CasADi's virtual machine is evaluated in blocks of at least this many poses, one per thread
#: (casadical.runtime._threads.evaluation_threads); UR10 `fk_jac_angles` on the VM, 2 cores: 300 poses 9.9 -> 5.4 ms,
#: 150 poses 5.0 ms either way
BLOCK_MIN = 100
#: poses per inner map of batches of 2 * MAP_CHUNK poses or more (:func:`mapped`): a flat map of N poses holds
#: every pose's summed outputs at once (a per-pose Gauss-Newton matrix: ~700 numbers per UR10 pose, 1.1 GB at
#: 200,000 poses) and one call's work memory per pose (the YS100 superset's positions: 115 numbers a pose, 730
#: MB at 200,000); a map of chunks holds one chunk's
MAP_CHUNK = 256


def mapped(fun: ca.Function, N: int, bcast, reduce) -> ca.Function:
    """``fun`` mapped over N poses: the inputs ``bcast`` broadcast, the outputs ``reduce`` summed; from
    ``2 * MAP_CHUNK`` poses on, a map of chunks of ``MAP_CHUNK`` poses."""
    bcast, reduce = list(bcast), list(reduce)
    name = fun.name()
    if N < 2 * MAP_CHUNK:
        return fun.map(f"{name}_{N}", "serial", N, bcast, reduce)
    M, R = divmod(N, MAP_CHUNK)
    inner = fun.map(f"{name}_{MAP_CHUNK}", "serial", MAP_CHUNK, bcast, reduce)
    pieces = [(0, M * MAP_CHUNK, inner.map(f"{name}_{MAP_CHUNK}x{M}", "serial", M, bcast, reduce))]
    if R:
        pieces.append((M * MAP_CHUNK, N, fun.map(f"{name}_{R}", "serial", R, bcast, reduce)))
    ins = [ca.MX.sym(fun.name_in(i), fun.size1_in(i), fun.size2_in(i) * (1 if i in bcast else N))
           for i in range(fun.n_in())]
    outs = []
    for a, b, F in pieces:
        outs.append(F.call([x if i in bcast else x[:, fun.size2_in(i) * a:fun.size2_in(i) * b]
                            for i, x in enumerate(ins)]))
    res = [sum(o[j] for o in outs) if j in reduce else ca.horzcat(*(o[j] for o in outs))
           for j in range(fun.n_out())]
    return ca.Function(f"{name}_{N}", ins, res)


def batch(mapped, N: int, bcast, compiled: bool) -> "Batch | Blocks":
    """A batch of N poses: ``mapped(n)`` (the Function mapped over n poses) as one :class:`Batch`, or on the VM
    as blocks of nearly equal size side by side (compiled code is ~10x faster than the VM: its blocks would be
    too small to gain from threads)."""
    k = 1 if compiled else max(1, min(evaluation_threads(), N // BLOCK_MIN))
    if k == 1:
        return Batch(mapped(N), N)
    cuts = [N * i // k for i in range(k + 1)]
    maps = {n: mapped(n) for n in {c - a for a, c in zip(cuts, cuts[1:])}}
    return Blocks([(a, Batch(maps[c - a], c - a)) for a, c in zip(cuts, cuts[1:])], bcast)


class Batch:
    """A mapped Function evaluated in place on preallocated numpy buffers.

    The parameter vector and ``base0`` are broadcast to every pose
    (``reduce_in``), and results are written straight into numpy memory:
    converting large CasADi matrices costs more than evaluating them.
    """

    def __init__(self, F: ca.Function, N: int):
        self.F, self.N = F, N
        self.buf, self.trigger = self.F.buffer()
        self.args = []
        for i in range(self.F.n_in()):
            sp = self.F.sparsity_in(i)
            shape = (sp.size2(), sp.size1())  # column-major storage = row-major transpose
            a = np.zeros(shape)
            self.args.append(a)
            self.buf.set_arg(i, memoryview(a))
        self.res = []
        for i in range(self.F.n_out()):
            sp = self.F.sparsity_out(i)
            r = np.zeros((sp.size2(), sp.size1()))
            self.res.append(r)
            self.buf.set_res(i, memoryview(r))

    def __call__(self, *inputs) -> list[np.ndarray]:
        self.evaluate(*inputs)
        return [r.copy() for r in self.res]

    def evaluate(self, *inputs) -> None:
        """Evaluate into the buffers (``self.res``, valid until the next evaluation)."""
        for a, x in zip(self.args, inputs):
            a.reshape(-1)[:] = np.asarray(x, dtype=float).reshape(-1)
        self.trigger()


class Blocks:
    """A batch as consecutive blocks of poses, each a :class:`Batch` of its own, evaluated in threads.

    CasADi releases the GIL while it evaluates, and each block has its own
    buffers (its own work memory), so the blocks run side by side. Every
    pose is computed alone by the same code: the results are the same bits
    as one batch's. Outputs are per pose (no sums), stacked pose by pose.
    """

    def __init__(self, blocks: list[tuple[int, Batch]], bcast: tuple):
        self.blocks, self.bcast = blocks, set(bcast)

    def __call__(self, *inputs) -> list[np.ndarray]:
        N = sum(b.N for _, b in self.blocks)
        inputs = [np.asarray(x, dtype=float) if i in self.bcast else np.asarray(x, dtype=float).reshape(N, -1)
                  for i, x in enumerate(inputs)]

        def block(start: int, batch: Batch) -> None:
            batch.evaluate(*(x if i in self.bcast else x[start:start + batch.N] for i, x in enumerate(inputs)))

        pool, futures = evaluation_pool(), []
        try:
            for start, batch in self.blocks:
                futures.append(pool.submit(block, start, batch))
            for f in futures:
                f.result()
        finally:
            wait(futures)   # on an error too: no block may write into its buffers after this call
        return [np.concatenate([b.res[j] for _, b in self.blocks]) for j in range(len(self.blocks[0][1].res))]
