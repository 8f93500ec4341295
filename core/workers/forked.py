"""A twin process for the second core: the same computation, half of each pass.

Two threads calling numpy at once hand the GIL to each other at every call,
and on a virtual machine each hand-over wakes the other core: the passes of a
320x180 frame make tens of thousands of calls of a few microseconds, and two
threads ran them barely faster than one (bench/bench_threads.py: a chain of
numpy calls over 28,800 rows, 1.28x on two threads, 1.86x on two processes).

``Twin`` forks the process at the start of a render loop (the frames of a
still, the samples of a path-traced image). Both processes then run the same
code on the same data, which is deterministic (per-pixel random numbers from
image-wide indices). At every whole-image pass (``Workers.map``) each computes
its half of the pixel ranges and the two exchange their results, so both hold
the whole pass and go on alike; the serial work between passes is done by
both. Only the parent (the leader) reports progress and decides to stop; when
the loop ends the child is killed, or parked (``serve``) until the next loop
resumes it (the next frame of an animation whose camera alone moved:
Workers.twin's Continuation). A loop the leader abandons mid-way (the
viewport's frame, for an edit: LoopAbandoned) is unwound by both: the
leader writes a word on a stop pipe, which the twin's interruptible ray
queries poll, and sends the abandon at the exchange the twin is at; the
twin answers with a checksum of its state, and is parked if the leader's
is the same. The copy-on-write page faults that follow a
fork are paid once per fork, not at every pass. Each pass is split where the
two processes took equal time on it the last times (twin_pass.py runs a
pass).

Exchange: each side writes a pass's results (pickle protocol 5, arrays as
raw buffers) into an anonymous memory file of its own, two of them used in
turn, and announces it on a pipe with the pass's number and size; a reader
is always done with a file before its writer reuses it (it answers each
message before the next is written). If the child dies, diverges or cannot
send, or does not answer in time (WAIT_SECONDS and WAIT_FACTOR, or the
Workers' own twin_wait), the parent computes the
child's ranges itself and goes on alone; an
exception raised by the pass in the child is raised again in the parent.

Only on Linux (no fork on Windows; unsafe on macOS with system frameworks);
elsewhere passes use threads.
"""

import os
import pickle
import select
import signal
import struct
import sys
import threading
import warnings

import numpy as np

AVAILABLE = sys.platform.startswith("linux") and hasattr(os, "fork") and hasattr(os, "memfd_create")

_HEADER = struct.Struct("<QQ")      # pass number, bytes in the memory file
IDLE_SECONDS = 60.0     # a parked twin that is not resumed within this exits
WAIT_SECONDS = 30.0     # the parent waits for the child's half of a pass at least this long, and
WAIT_FACTOR = 20.0      # this many times its own half's time: then it goes on alone (a child
                        # stuck in a lock some other thread held at the fork never answers)


class TwinLost(RuntimeError):
    """The other process ended or diverged."""


class TwinSilent(TwinLost):
    """The other process did not answer in time (it may be stuck for good)."""


class LoopAbandoned(Exception):
    """The leader stopped a loop mid-way (the viewport's frame, for an edit).
    Raised in the leader by whatever stopped it, and in the twin at its next
    exchange: both unwind the loop, and the twin may be kept (``abandon``)."""


_local = threading.local()     # the render loop's Twin, on the thread that runs it


def active():
    """The Twin of the render loop this thread runs, or None (another thread
    of the process, a viewport's say, never exchanges with it)."""
    return getattr(_local, "twin", None)


def in_twin():
    """True in the child process of a render loop (not the leader)."""
    twin = active()
    return twin is not None and not twin.leader


def told_to_stop():
    """In the child of a render loop: the leader abandoned the loop, which
    this side unwinds at its next poll (Twin.told_to_stop). False elsewhere."""
    twin = active()
    return twin is not None and twin.told_to_stop()


class Twin:
    """The two processes of a forked render loop; ``leader`` in the parent."""

    def __init__(self):
        self.leader = True
        self.pid = None
        self.calls = 0
        self.in_pass = False
        self.balance = {}       # pass -> the parent's share of its pixels
        self.wait = (WAIT_SECONDS, WAIT_FACTOR)     # how long the parent waits for a pass (start)
        self.hung = False       # the parent went on alone: the child did not answer in time
        self.abandoned = None   # (child) the fingerprint function of a loop the leader abandoned
        self._files = None
        self._pipes = None
        self._stop = None       # a pipe of its own: the parent's "stop now" (``abandon``)
        self.stopping = False   # (child) the loop was unwound on that word

    @staticmethod
    def start(balance=None, wait=None):
        """Fork; returns the Twin in both processes (None if it could not fork).
        balance: the passes' splits learnt by an earlier loop; wait:
        (seconds, factor): the parent waits for the child's half of a pass
        the longer of seconds and factor times its own half's time (None:
        WAIT_SECONDS and WAIT_FACTOR)."""
        twin = Twin()
        twin.balance = dict(balance or {})
        if wait is not None:
            twin.wait = (float(wait[0]), float(wait[1]))
        files, pipes = [], []
        try:
            files = [os.memfd_create("restir-twin", os.MFD_CLOEXEC) for _ in range(4)]
            pipes = [os.pipe(), os.pipe(), os.pipe()]   # parent -> child, child -> parent, stop
            with warnings.catch_warnings():
                # Python 3.12+ warns that a fork of a multi-threaded process
                # (Blender's is) may leave the child stuck on a lock another
                # thread held: such a child never answers, and the parent
                # goes on alone after WAIT_SECONDS (see above).
                warnings.filterwarnings("ignore", r"This process \(pid=\d+\) is multi-threaded",
                                        DeprecationWarning)
                pid = os.fork()
        except OSError:
            for fd in files + [fd for p in pipes for fd in p]:
                os.close(fd)
            return None
        (p2c_r, p2c_w), (c2p_r, c2p_w), (stop_r, stop_w) = pipes
        if pid == 0:
            # Nothing may raise out of here in the child: it would unwind
            # through the caller's stack (Blender's render code) in a copy of
            # the process.
            try:
                twin.leader = False
                os.close(p2c_w)
                os.close(c2p_r)
                os.close(stop_w)
                os.set_blocking(stop_r, False)
                twin._pipes = (p2c_r, c2p_w)                 # read from, write to
                twin._stop = stop_r
                twin._files = (files[2:], files[:2])         # mine, theirs
                if threading.current_thread() is threading.main_thread():
                    signal.signal(signal.SIGINT, signal.SIG_DFL)
                _die_with_parent()
            except BaseException:  # noqa: BLE001 -- the child must not return into the parent's code
                os._exit(1)
        else:
            twin.pid = pid
            os.close(p2c_r)
            os.close(c2p_w)
            os.close(stop_r)
            twin._pipes = (c2p_r, p2c_w)
            twin._stop = stop_w
            twin._files = (files[:2], files[2:])
        _local.twin = twin
        return twin

    def park(self):
        """(parent) Leave the twin waiting for the next loop (``resume``);
        this thread has no active twin meanwhile."""
        if active() is self:
            _local.twin = None

    def resume(self, fn, args):
        """(parent) Start the next loop in the parked twin: it runs
        fn(*its_state, *args) (see ``serve``). False if the twin is gone."""
        if self.pid is None:
            return False
        try:
            done, _ = os.waitpid(self.pid, os.WNOHANG)
        except ChildProcessError:
            done = self.pid
        if done:                    # exited (idle too long, or killed)
            self.pid = None
            return False
        k = self.calls
        try:
            self._send(k, ("resume", fn, args))
        except TwinLost:
            return False
        self.calls += 1
        _local.twin = self
        return True

    def abandon(self, fingerprint, state):
        """(parent) After the leader unwound a loop it abandoned
        (LoopAbandoned): tell the twin, which unwinds it at the exchange it
        is at, and compare the states both reached: fingerprint(*state), a
        module-level function, is computed on each side. True if they agree
        (the twin then waits for ``resume``, as after a completed loop);
        otherwise, or if the twin does not answer within the wait, it is
        ended. A pass the leader left half done may have written rows of
        the state only the twin finished: the fingerprints then differ."""
        k = self.calls
        try:
            # First a word on the stop pipe, which the twin's interruptible
            # passes poll (``told_to_stop``): it stops at its next ray
            # batch, not at the end of its half of the pass. Then the
            # abandon itself, at the exchange it is at.
            os.write(self._stop, b"!")
            self._send(k, ("abandon", fingerprint))
            mine = fingerprint(*state)
            self._receive(k, self.wait[0])          # the twin's half of the pass it was in
            tag, theirs = self._receive(k + 1, self.wait[0])
        except (TwinLost, OSError):
            self.end()
            return False
        self.calls = k + 2
        if tag != "ack" or theirs != mine:
            self.end()
            return False
        self.park()
        return True

    def serve(self, state):
        """(child) Wait for the parent's next loop and run it, again and
        again: state = fn(*state, *args) for each (fn, args) resumed with.
        A loop the leader abandoned (LoopAbandoned) must still return the
        state it reached; this side then acknowledges with its fingerprint
        (``abandon``). Exits when no loop comes for IDLE_SECONDS, when the
        parent is gone, when a loop fails (the parent then goes on alone),
        or when an abandon arrives here, after a loop this side completed
        and the leader did not. Never returns."""
        try:
            self.acknowledge(state)
            while True:
                ready, _, _ = select.select([self._pipes[0]], [], [], IDLE_SECONDS)
                if not ready:
                    break
                k = self.calls
                tag, *message = self._receive(k)
                self.calls += 1
                if tag != "resume":
                    break
                fn, args = message
                state = fn(*state, *args)
                self.acknowledge(state)
        except BaseException:  # noqa: BLE001 -- the parent gone or a loop failed: exit, never return
            pass
        os._exit(0)

    def acknowledge(self, state):
        """(child) If the leader abandoned the last loop, send it this side's
        fingerprint of the state reached (see ``abandon``). A loop this
        side stopped on the stop word outside a pass has yet to take the
        abandon at the exchange it was at."""
        if self.stopping and self.abandoned is None:
            k = self.calls
            self.calls += 1
            self._send(k, ("stopped",))
            tag, *message = self._receive(k)
            if tag != "abandon":
                raise TwinLost(f"stopped, and the leader sent {tag!r}")
            self.abandoned = message[0]
        fingerprint, self.abandoned = self.abandoned, None
        if fingerprint is not None:
            self.stopping = False
            try:
                while os.read(self._stop, 64):      # the stop word is read now, never in the next loop
                    pass
            except BlockingIOError:
                pass
            self._send(self.calls, ("ack", fingerprint(*state)))
            self.calls += 1

    def told_to_stop(self):
        """(child) Whether the leader abandoned the loop (the stop word
        arrived); the caller then unwinds it with LoopAbandoned."""
        if self.leader or self._stop is None:
            return False
        if not self.stopping:
            ready, _, _ = select.select([self._stop], [], [], 0)
            self.stopping = bool(ready)
        return self.stopping

    def exchange(self, payload, timeout=None):
        """Send this side's payload of the next pass and return the other's
        (TwinLost if it does not come within timeout seconds)."""
        k = self.calls
        self.calls += 1
        self._send(k, payload)
        return self._receive(k, timeout)

    def _send(self, k, payload):
        buffers = []
        head = pickle.dumps(payload, protocol=5, buffer_callback=buffers.append)
        raws = [b.raw() for b in buffers]
        sizes = [len(head)] + [r.nbytes for r in raws]
        chunks = [struct.pack(f"<Q{len(sizes)}Q", len(sizes), *sizes), head] + raws
        size = sum(memoryview(c).nbytes for c in chunks)
        # Written over the last payload but one in this file, never
        # truncated: the file keeps its pages, and the reader reads ``size``
        # bytes (truncating and refilling it cost a page fault and a zeroed
        # page per 4 KiB: half the time of sending a ReSTIR pass's rows).
        fd = self._files[0][k % 2]
        done = 0
        while chunks:
            n = os.pwritev(fd, chunks[:512], done)
            done += n
            while chunks and n >= memoryview(chunks[0]).nbytes:
                n -= memoryview(chunks.pop(0)).nbytes
            if chunks and n:
                chunks[0] = memoryview(chunks[0]).cast("B")[n:]
        try:
            os.write(self._pipes[1], _HEADER.pack(k, size))
        except (BrokenPipeError, OSError) as e:
            raise TwinLost(f"the other process is gone: {e}") from e

    def _receive(self, k, timeout=None):
        if timeout is not None:
            ready, _, _ = select.select([self._pipes[0]], [], [], timeout)
            if not ready:
                raise TwinSilent(f"the other process did not answer within {timeout:.1f} s")
        header = _read_exactly(self._pipes[0], _HEADER.size)
        got_k, size = _HEADER.unpack(header)
        if got_k != k:
            raise TwinLost(f"the processes diverged (pass {got_k} against {k})")
        data = np.empty(size, np.uint8)     # every byte is read into: not zeroed first
        view = memoryview(data)
        fd = self._files[1][k % 2]
        done = 0
        while done < size:
            n = os.preadv(fd, [view[done:]], done)
            if n <= 0:
                raise TwinLost("short read of the other process's results")
            done += n
        (count,) = struct.unpack_from("<Q", data, 0)
        sizes = struct.unpack_from(f"<{count}Q", data, 8)
        offset = 8 + 8 * count
        head = view[offset:offset + sizes[0]]
        offset += sizes[0]
        buffers = []
        for s in sizes[1:]:
            buffers.append(view[offset:offset + s])
            offset += s
        return pickle.loads(head, buffers=buffers)

    def end(self):
        """Parent: kill and reap the child. Child: exit now (never returns)."""
        if not self.leader:
            os._exit(0)
        if active() is self:
            _local.twin = None
        if self.pid is not None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            while True:
                try:
                    os.waitpid(self.pid, 0)
                    break
                except InterruptedError:
                    continue
                except ChildProcessError:
                    break
            self.pid = None
        stop = [] if self._stop is None else [self._stop]
        for fd in list(self._pipes) + list(self._files[0]) + list(self._files[1]) + stop:
            try:
                os.close(fd)
            except OSError:
                pass
        self._pipes, self._files, self._stop = (), ((), ()), None


def _read_exactly(fd, n):
    out = b""
    while len(out) < n:
        try:
            chunk = os.read(fd, n - len(out))
        except InterruptedError:
            continue
        if not chunk:
            raise TwinLost("the other process is gone")
        out += chunk
    return out


def _die_with_parent():
    """The child is killed if the parent dies (Linux prctl PR_SET_PDEATHSIG)."""
    try:
        import ctypes  # noqa: PLC0415 (inside the try: Linux only)
        libc = ctypes.CDLL(None)
        libc.prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass
