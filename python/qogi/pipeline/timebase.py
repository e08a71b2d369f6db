"""The run's time base: what ``time_s`` says about the frames, and the blocks
the pipeline streams them in.

A camera's nominal frame interval is ``1 / frame_rate_hz``; real recordings
drop frames (an interval of two or more nominal ones) and may stop and resume
(a gap of seconds to hours). Velocimetry measures displacement over the real
interval between the two frames of a pair, so every pair's duration is kept
here in nominal intervals (the pipeline's velocity unit is px per nominal
interval). Pairs across a gap longer than :data:`MAX_GAP_INTERVALS` nominal
intervals are not used: the run is cut there into segments analysed apart.

Segments are streamed in blocks of at most ``block_frames`` frames (the
pipeline's memory bound), each read with a few frames of overlap on either
side so the velocimetry's pairs and frame velocities at a block's edges are
those of the whole recording.
"""

from __future__ import annotations

import dataclasses
from typing import List, Tuple

import numpy as np

__all__ = [
    "Timebase",
    "frame_timebase",
    "Block",
    "stream_blocks",
    "MAX_GAP_INTERVALS",
    "DROP_THRESHOLD",
]

#: A pair whose interval exceeds this many nominal intervals is not used (the
#: run is cut there): the plume's structures no longer carry from one frame to
#: the next (at 15 Hz a lab plume crosses ~20 px per frame), and a gap of
#: minutes breaks the flow's warm start and the transport's steady levels.
MAX_GAP_INTERVALS = 4.0
#: An interval longer than this many nominal ones counts as dropped frames
#: (``round(interval) - 1`` of them); shorter is jitter.
DROP_THRESHOLD = 1.5


@dataclasses.dataclass(frozen=True)
class Timebase:
    """Frame times of a run and what they imply.

    Attributes
    ----------
    time_s : ndarray (T,)
        The run's frame times [s].
    interval_s : float
        The nominal frame interval, 1 / frame rate [s].
    pair_intervals : ndarray (T - 1,)
        Interval between consecutive frames, in nominal intervals (1.0 for a
        camera that drops nothing).
    dropped : list of (index, missing)
        Each place where frames are missing: ``index`` (of the run's frame
        after which they are missing) and how many (``round(interval) - 1``).
    segments : list of (start, stop)
        Stretches of the run (indices into it, stop exclusive) without a gap
        longer than :data:`MAX_GAP_INTERVALS`; pairs are formed only inside one.
    """

    time_s: np.ndarray
    interval_s: float
    pair_intervals: np.ndarray
    dropped: List[Tuple[int, int]]
    segments: List[Tuple[int, int]]

    @property
    def n_dropped(self) -> int:
        """Frames missing in total (also across cut gaps)."""
        return int(sum(m for _, m in self.dropped))

    @property
    def gaps(self) -> List[Tuple[int, float]]:
        """The cuts between segments: (index of the frame before, gap [s])."""
        return [
            (b - 1, float(self.time_s[b] - self.time_s[b - 1])) for (_, b) in self.segments[:-1]
        ]


def frame_timebase(
    time_s, frame_rate_hz: float, max_gap_intervals: float = MAX_GAP_INTERVALS
) -> Timebase:
    """The :class:`Timebase` of frames at ``time_s`` [s] from a camera at
    ``frame_rate_hz`` [Hz]."""
    t = np.asarray(time_s, dtype=np.float64)
    if not (np.isfinite(frame_rate_hz) and frame_rate_hz > 0):
        raise ValueError(f"frame_rate_hz must be > 0; got {frame_rate_hz}")
    dt = 1.0 / float(frame_rate_hz)
    r = np.diff(t) / dt
    dropped = [(int(i), int(round(r[i])) - 1) for i in np.flatnonzero(r > DROP_THRESHOLD)]
    cuts = np.flatnonzero(r > max_gap_intervals) + 1
    edges = [0] + [int(c) for c in cuts] + [len(t)]
    segments = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    return Timebase(t, dt, r, dropped, segments)


@dataclasses.dataclass(frozen=True)
class Block:
    """One block of a run: the frames ``read`` (start, stop) are analysed,
    those in ``keep`` (start, stop; inside ``read``) are reported. Indices
    into the run."""

    read: Tuple[int, int]
    keep: Tuple[int, int]

    @property
    def offset(self) -> int:
        """Index of the first kept frame within the read ones."""
        return self.keep[0] - self.read[0]

    @property
    def n_keep(self) -> int:
        return self.keep[1] - self.keep[0]


def stream_blocks(
    segments: List[Tuple[int, int]], block_frames: int, overlap: int = 4
) -> List[Block]:
    """Blocks of at most ``block_frames`` kept frames covering every segment
    (a segment is split into equal parts), each read with up to ``overlap``
    frames more on either side within its segment."""
    if block_frames < 1:
        raise ValueError(f"block_frames must be >= 1; got {block_frames}")
    out = []
    for a, b in segments:
        n = b - a
        parts = max(1, -(-n // block_frames))
        edges = [a + (n * i) // parts for i in range(parts + 1)]
        for k0, k1 in zip(edges[:-1], edges[1:]):
            out.append(Block((max(a, k0 - overlap), min(b, k1 + overlap)), (k0, k1)))
    return out
