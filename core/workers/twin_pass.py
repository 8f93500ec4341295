"""One whole-image pass computed by the two processes of a render loop
(core/workers/forked.py): each takes its share of the pixel ranges, and the
two exchange their results, so both hold the whole pass."""

import pickle
import time
import traceback

from .forked import LoopAbandoned, TwinLost, TwinSilent


def run_pass(twin, fn, parts, written):
    """(ranges, [fn(a, b) for (a, b) in ranges]) with the twin computing its
    share: ``parts`` as given, or, for two ranges, split where the two
    processes took equal time on this pass the last times (the bottom half
    of a courtyard, ground and walls, costs twice the sky above it). Both
    processes derive the split from the times they exchanged, so they agree;
    the image does not depend on it (per-pixel random numbers).

    written: whole-image arrays fn fills in place by rows; the other side's
    rows of them are copied in. If the twin is lost the parent computes its
    ranges too and goes on alone (the child exits)."""
    key = (getattr(fn, "__qualname__", ""), parts[0][0], parts[-1][1])
    if len(parts) == 2:
        a, b = parts[0][0], parts[-1][1]
        m = a + int(round(twin.balance.get(key, 0.5) * (b - a)))
        parts = [(a, m), (m, b)]
    mine, theirs = _split(twin, parts)
    twin.in_pass = True         # passes nested in fn run whole on each side
    t0 = time.perf_counter()
    try:
        results = [fn(a, b) for a, b in mine]
        payload = ("ok", results, [[w[a:b] for a, b in mine] for w in written], time.perf_counter() - t0)
    except LoopAbandoned:
        if twin.leader:
            raise
        payload = ("stopped",)  # (child) told to stop: the leader's abandon comes in exchange
    except Exception as e:
        if twin.leader:
            raise
        payload = ("error", _picklable(e), traceback.format_exc())
    finally:
        twin.in_pass = False
    # The parent does not wait forever: a child that does not answer is
    # left, and its ranges computed here.
    wait = max(twin.wait[0], twin.wait[1] * (time.perf_counter() - t0)) if twin.leader else None
    try:
        other = twin.exchange(payload, wait)
    except TwinLost as e:
        twin.hung = isinstance(e, TwinSilent)
        twin.end()              # the child exits here; the parent kills it
        return parts, results + [fn(a, b) for a, b in theirs]
    if payload[0] == "error":   # the parent raises it
        twin.end()
    if other[0] == "abandon":   # (child) the leader stopped the loop: unwind it as it did
        twin.abandoned = other[1]
        raise LoopAbandoned("the leader abandoned the loop")
    if other[0] == "error":
        twin.end()
        raise other[1]
    _, their_results, their_rows, their_seconds = other
    for w, rows in zip(written, their_rows):
        for (a, b), part in zip(theirs, rows):
            w[a:b] = part
    if len(parts) == 2:
        seconds = (payload[3], their_seconds) if twin.leader else (their_seconds, payload[3])
        _rebalance(twin, key, parts, seconds)
    return parts, (results + their_results if twin.leader else their_results + results)


def _picklable(e):
    try:
        pickle.loads(pickle.dumps(e))
        return e
    except Exception:  # noqa: BLE001 -- not picklable: sent as a RuntimeError
        out = RuntimeError(f"{type(e).__name__}: {e}")
        for note in getattr(e, "__notes__", ()):    # where it happened (core/util/errors.py)
            out.add_note(note)
        return out


def _split(twin, parts):
    """(mine, theirs) of a pass's ranges: the parent takes the first half."""
    half = (len(parts) + 1) // 2
    return (parts[:half], parts[half:]) if twin.leader else (parts[half:], parts[:half])


def _rebalance(twin, key, parts, seconds):
    """The parent's share of the next pass ``key`` from the (parent,
    child) seconds of this one over ``parts``: each side's pixels per
    second, halfway towards equal times (stable against noise)."""
    (a, m), (_, b) = parts
    if min(seconds) <= 0 or m <= a or b <= m:
        return
    share = (m - a) / (b - a)
    fast = (m - a) / seconds[0]
    slow = (b - m) / seconds[1]
    even = fast / (fast + slow)
    twin.balance[key] = min(0.9, max(0.1, 0.5 * share + 0.5 * even))
