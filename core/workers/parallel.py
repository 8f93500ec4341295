"""Both cores for whole-image passes: pixel ranges on worker threads.

numpy releases the GIL inside its array loops and Embree inside its queries,
so two threads each running a pass over half of the pixels overlap well
(bench/bench_restir.py times one and two workers). A pass is split into contiguous pixel
ranges; every range is computed from the same inputs with the same per-pixel
random numbers, so the result does not depend on the number of workers.

Ray queries made from a worker run on that worker alone: the Accel's own
two-thread split would only oversubscribe the cores.

With ``processes`` (Linux), a render loop over an image of two ranges runs
inside ``Workers.twin``: the process forks, and each pass's second range is
computed by the child (core/workers/forked.py). Two threads hand the GIL to each
other at every numpy call, which on such images costs about what the second
core gives; larger images (more ranges than workers, whose numpy calls are
long enough for threads) stay on threads.
"""

import contextlib
import ctypes
import ctypes.util
import dataclasses
import os
import threading
from concurrent.futures import ThreadPoolExecutor, wait

import numpy as np

from . import forked, twin_pass

_local = threading.local()
MIN_PIXELS_PER_WORKER = 4096     # below this a pass runs on the calling thread
# ... or, in a twin loop, below this: a process pays one exchange per pass
# (about a millisecond), not a hand-over of the GIL at every numpy call
# (the temporal gradients' 6420 re-drawn samples of a 320x180 frame, 45 ms
# on one core, were traced whole by both processes).
MIN_PIXELS_PER_TWIN = 1024
MAX_PIXELS_PER_RANGE = 1 << 17   # above this a pass is split into more ranges than workers


def in_worker():
    """True on a Workers thread (Accel then traces on the calling thread)."""
    return getattr(_local, "worker", False) or forked.active() is not None


@dataclasses.dataclass
class Continuation:
    """How a render loop's twin may go on into the next loop (Workers.twin).

    token: () -> what must be equal for the twin's state to be the
    caller's (None: never); state: the objects the twin's next loop starts
    from (its copies); resume: module-level function (state..., patch,
    args...) -> the new state, run in the twin; args: picklable, sent to
    it; patch: (parked state, parked token) -> what brings the twin's copies
    of a parked state whose token differs to the caller's (picklable; None
    where nothing does), passed to resume (None when the tokens are equal);
    complete: set by the loop when it ran to its end; fingerprint:
    module-level function (state...) -> a value both processes compute
    after the leader abandoned the loop (forked.LoopAbandoned), to keep the
    twin if they agree (None: the twin of an abandoned loop is ended).
    resume must then return the state it reached all the same."""
    token: object
    state: tuple
    resume: object
    args: tuple
    complete: bool = False
    patch: object = None
    fingerprint: object = None


def _mark_worker():
    _local.worker = True


class Workers:
    """A small pool that maps a function over contiguous pixel ranges."""

    def __init__(self, threads=None, max_range=MAX_PIXELS_PER_RANGE, processes=True,
                 twin_wait=None, twin_max_pixels=None):
        """processes: render loops in ``twin`` may fork a second process
        (Linux, two workers); False keeps every pass on threads. twin_wait:
        (seconds, factor), how long the leader waits for the twin's half of
        a pass before it goes on alone (forked.Twin.start; None: its
        defaults). After a twin did not answer in time these workers fork no
        more (processes goes False): a fork that hung once may hang again,
        and each costs the wait. (A twin that exited, say because it could
        not follow the scene's edits, is forked anew for the next loop.)
        twin_max_pixels: larger images stay on threads (None: any image of
        two ranges)."""
        self.threads = max(1, threads or min(os.cpu_count() or 1, 2))
        self.max_range = max(1, int(max_range))
        self.processes = bool(processes) and forked.AVAILABLE and self.threads == 2
        self.twin_wait = None if twin_wait is None else tuple(twin_wait)
        self.twin_max_pixels = twin_max_pixels
        self._balance = {}
        self._parked = None             # (Twin, token) waiting for the next loop
        self._pool = (ThreadPoolExecutor(self.threads, initializer=_mark_worker)
                      if self.threads > 1 else None)

    def ranges(self, n):
        """Contiguous (start, stop) ranges covering [0, n): one per worker
        used, or more where that keeps each under ``max_range`` pixels (the
        temporaries of a pass are sized by its range, not by the image)."""
        twin = forked.active()
        least = MIN_PIXELS_PER_TWIN if twin is not None and not twin.in_pass else MIN_PIXELS_PER_WORKER
        parts = 1 if self._pool is None else max(1, min(self.threads, n // least))
        parts = max(parts, -(-n // self.max_range))
        bounds = np.linspace(0, n, parts + 1).astype(np.int64)
        return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]

    def map(self, fn, n, written=()):
        """[fn(start, stop) for each range of [0, n)], in range order.

        written: whole-image arrays that fn fills in place by rows; declared
        so that rows filled by the twin process (``twin``) reach them."""
        parts = self.ranges(n)
        twin = forked.active()
        if twin is not None and not twin.in_pass and len(parts) > 1:
            return twin_pass.run_pass(twin, fn, parts, written)[1]
        if self._pool is None or len(parts) == 1 or in_worker():
            return [fn(a, b) for a, b in parts]
        futures = [self._pool.submit(fn, a, b) for a, b in parts]
        # Every range finishes (or fails) before this returns or raises: a
        # worker must never outlive the call and trace into a freed scene.
        wait(futures)
        return [f.result() for f in futures]

    def map_into(self, fn, n, out=None, written=()):
        """concat_rows(self.map(fn, n)) without holding every range's result:
        each range's arrays are copied into whole-image arrays as soon as it
        returns, then dropped. out: those arrays (the structure fn returns,
        with (n, ...) arrays, e.g. of narrower types); allocated from the
        first result returned if None. Constants in the result (None, sizes)
        are taken from that first result. written: as for map."""
        parts = self.ranges(n)
        twin = forked.active()
        if twin is not None and not twin.in_pass and len(parts) > 1:
            for (a, b), part in zip(*twin_pass.run_pass(twin, fn, parts, written)):
                if out is None:
                    out = _alike(part, n)
                _write_rows(out, part, a, b)
            return out
        lock = threading.Lock()
        holder = [out]

        def run(a, b):
            part = fn(a, b)
            with lock:
                if holder[0] is None:
                    holder[0] = _alike(part, n)
                dst = holder[0]
            _write_rows(dst, part, a, b)
            return None

        self.map(run, n, written)
        return holder[0]

    @contextlib.contextmanager
    def twin(self, n, keep=None):
        """A render loop over images of n pixels, run by two processes (see
        core/workers/forked.py) when ``processes`` is on and n makes two ranges.
        Yields True in the leading process (the caller's), False in the
        twin, which must do nothing but compute (no reports, no stopping).

        keep: a Continuation: when the loop has run to its end
        (``keep.complete``), the twin is not ended but parked with
        ``keep.state``, and the next loop whose ``keep.token()`` equals the
        parked one, or whose ``keep.patch`` brings the parked state to its
        own, resumes it (``keep.resume(*state, patch, *keep.args)`` in the
        twin) instead of forking again: the page faults that follow a fork
        are paid once per animation, not once per frame. A loop the leader
        abandons (forked.LoopAbandoned) parks the twin too when
        ``keep.fingerprint`` finds both states alike (forked.Twin.abandon):
        the viewport's frame restarted after an edit forks no more.
        Otherwise the twin is ended when the block ends, in both processes."""
        outer = forked.active()
        if outer is not None:       # a loop inside a twin's loop: its roles hold
            yield outer.leader
            return
        use = self.processes and self._pool is not None and len(self.ranges(n)) == 2 and not in_worker() \
            and (self.twin_max_pixels is None or n <= self.twin_max_pixels)
        twin = None
        parked, self._parked = self._parked, None
        if parked is not None:
            parked_twin, parked_token, parked_state = parked
            patch = False
            if use and keep is not None and parked_token is not None:
                token = keep.token()
                if token == parked_token:
                    patch = None
                elif token is not None and keep.patch is not None:
                    patch = keep.patch(parked_state, parked_token) or False
            if patch is not False and parked_twin.resume(keep.resume, (patch,) + tuple(keep.args)):
                twin = parked_twin
            else:
                parked_twin.end()
        if twin is None and use:
            twin = forked.Twin.start(balance=self._balance, wait=self.twin_wait)
        if twin is None:
            yield True
            return
        completed = abandoned = False
        try:
            yield twin.leader
            completed = keep is not None and keep.complete
        except forked.LoopAbandoned:
            # The leader stopped the loop (the twin unwinds it at its next
            # exchange): both may go on from the state they reached.
            abandoned = keep is not None and keep.fingerprint is not None
            raise
        finally:
            self._balance = dict(twin.balance)     # where to split the passes of the next loop
            if twin.leader and twin.hung:
                self.processes = False
            if (completed or abandoned) and not twin.leader:
                twin.serve(keep.state)      # never returns
            if abandoned and twin.pid is not None:
                completed = twin.abandon(keep.fingerprint, keep.state)
            if completed and twin.pid is not None:
                twin.park()
                self._parked = (twin, keep.token(), keep.state)
            else:
                twin.end()      # the twin exits here

    def end_twin(self):
        """End a twin parked for the next loop (Workers.twin)."""
        if self._parked is not None:
            self._parked[0].end()
            self._parked = None

    def close(self):
        self.end_twin()
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None


SERIAL = Workers(1)


def _libc_trim():
    """glibc's malloc_trim, or None where the C library has none."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError, TypeError):
        return None
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return trim


_TRIM = _libc_trim() if os.name == "posix" else None


def release_free_memory():
    """Give the pages freed inside the C heap back to the system (glibc).

    numpy's temporaries of the pixel ranges are allocated from the heaps of
    the worker threads; once freed, their pages stay resident until the heap
    reuses them, so after a frame the process holds hundreds of MB it does not
    use (bench/bench_memory.py). Called once per frame: trimming at every free
    instead (a small M_TRIM_THRESHOLD) makes every range fault its pages anew."""
    if _TRIM is not None:
        _TRIM(0)


def concat_rows(parts, consume=False):
    """Concatenate per-range results: arrays, or tuples or dataclasses of
    arrays (same type). consume: ``parts`` is emptied as it is copied, so
    each part's arrays are freed once in place and the peak stays near one
    copy of the result (the parts must not be used afterwards)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    if isinstance(first, np.ndarray):
        if not consume:
            return np.concatenate(parts)
        out = np.empty((sum(len(p) for p in parts),) + first.shape[1:], np.result_type(*parts))
        del first
        offset = 0
        for i in range(len(parts)):
            n = len(parts[i])
            out[offset:offset + n] = parts[i]
            parts[i] = None
            offset += n
        return out
    if first is None or np.isscalar(first) or isinstance(first, (str, list)):
        return first            # per-call constants (sizes, names) are the same in every part
    if isinstance(first, tuple):
        columns = [[p[i] for p in parts] for i in range(len(first))]
        kind = None
    else:
        names = list(first.__dataclass_fields__)
        columns = [[getattr(p, f) for p in parts] for f in names]
        kind = type(first)
    del first
    if consume:
        parts.clear()           # the columns now hold the only references
    joined = [concat_rows(c, consume) for c in columns]
    return tuple(joined) if kind is None else kind(**dict(zip(names, joined)))


def _fields(x):
    """(constructor, items) of a tuple or dataclass result, or None for a leaf."""
    if isinstance(x, tuple):
        return tuple, list(x)
    if hasattr(x, "__dataclass_fields__"):
        names = list(x.__dataclass_fields__)
        return (lambda items: type(x)(**dict(zip(names, items)))), [getattr(x, f) for f in names]
    return None


def _alike(part, n):
    """Empty whole-image arrays shaped like a range's result (n rows)."""
    if isinstance(part, np.ndarray):
        return np.empty((n,) + part.shape[1:], part.dtype)
    if hasattr(part, "whole_image"):
        return part.whole_image(n)      # a store of its own (Reservoirs)
    nested = _fields(part)
    if nested is None:
        return part             # a per-call constant
    make, items = nested
    return make([_alike(i, n) for i in items])


def _write_rows(dst, part, a, b):
    """dst[a:b] = part, through tuples and dataclasses (constants are skipped)."""
    if isinstance(dst, np.ndarray):
        if len(part) != b - a:
            raise ValueError(f"a range of {b - a} rows returned {len(part)}")
        dst[a:b] = part
        return
    if hasattr(dst, "write_rows"):
        dst.write_rows(a, b, part)
        return
    nested = _fields(dst)
    if nested is None:
        return
    _make, items = nested
    for d, p in zip(items, _fields(part)[1]):
        _write_rows(d, p, a, b)
