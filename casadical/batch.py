"""A mapped CasADi Function evaluated in place on numpy buffers, whole or in blocks on threads."""

from __future__ import annotations

from concurrent.futures import wait

import casadi as ca
import numpy as np

from .threads import evaluation_pool, evaluation_threads

#: a batch on CasADi's virtual machine is evaluated in blocks of at least this many poses, one per thread
#: (casadical.threads.evaluation_threads); UR10 `fk_jac_angles` on the VM, 2 cores: 300 poses 9.9 -> 5.4 ms,
#: 150 poses 5.0 ms either way
BLOCK_MIN = 100


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
