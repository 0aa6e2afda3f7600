"""Rows (hot parts + interpreted rows) in program order → Targets."""
from __future__ import annotations

import numpy as np

from ..model import Targets


def _empty_targets() -> Targets:
    return Targets(
        poses=np.zeros((0, 6)), spans=np.zeros((0, 3, 2), np.int64), abc_spans=np.zeros((0, 3, 2), np.int64),
        file=np.zeros(0, np.int32),
        line=np.zeros(0, np.int32), col=np.zeros(0, np.int32), frame=np.zeros(0, np.int32),
        motion=np.zeros(0, np.int8), config=np.zeros((0, 2), np.int16),
    )


class Assembly:
    """Rows (hot parts + interpreted rows) in program order → Targets. (methods of the Reader)"""

    def assemble(self) -> Targets:
        """All rows (hot parts + the interpreter's rows) in program order → Targets: frames of
        hot rows from the timeline, partial aggregates filled, only emitted rows kept."""
        c = self.cold
        n = len(c["key"])
        parts = list(self.hot.parts)
        self.timeline.sort(key=lambda t: t[0])  # (already in order: one file after the other, line by line)
        tk = np.array([t[0] for t in self.timeline], np.int64)
        tf = np.array([t[1] for t in self.timeline], np.int32)
        for p in parts:
            p.pop("spl", None)
            m = len(p["key"])
            # the frame in force at their line: the last timeline entry before them
            at = np.searchsorted(tk, p["key"], "right") - 1
            if (at < 0).any():  # (cannot happen after a DEF: it starts the timeline)
                tk, tf = np.concatenate([[-1], tk]), np.concatenate([[self.start_frame()], tf])
                self.timeline.insert(0, (-1, int(tf[0]), None))
                at = at + 1
            f = tf[at]
            p["frame"] = f.astype(np.int32)
            p["emit"] = np.ones(m, bool)
            if (f < 0).any():
                left = np.flatnonzero(f < 0)
                for r, first, cnt in zip(*np.unique(at[left], return_index=True, return_counts=True)):
                    reason = self.timeline[r][2] if r >= 0 else None
                    i = left[first]
                    self.count_unknown(-1, reason, int(cnt), (int(p["key"][i]), int(p["line"][i]), int(p["col"][i]),
                                                                  self.files[int(p["file"][i])]))
        if n:
            parts.append(dict(
                key=np.array(c["key"], np.int64), pose=np.array(c["pose"], float).reshape(n, 6),
                written=np.array(c["written"], bool).reshape(n, 6), spans=np.array(c["spans"], np.int64).reshape(n, 12),
                file=np.array(c["file"], np.int32), line=np.array(c["line"], np.int32),
                col=np.array(c["col"], np.int32), motion=np.array(c["motion"], np.int8),
                chain=np.array(c["chain"], bool), frame=np.array(c["frame"], np.int32),
                emit=np.array(c["emit"], bool), config=np.array(c["config"], np.int16).reshape(n, 2),
            ))
        if not parts:
            return _empty_targets()

        def column(k, rows=None):
            v = np.concatenate([p[k] for p in parts]) if len(parts) > 1 else parts[0][k]
            return v if rows is None else v[rows]

        order = np.argsort(column("key"), kind="stable")
        pose, written, chain = column("pose", order), column("written", order), column("chain", order)
        emit = column("emit", order)
        # partial aggregates: a component not written comes from the last chain row before
        # (the current position; barrier rows hold NaN)
        m = len(pose)
        ar = np.arange(m)
        for k in range(6):
            w = written[:, k]
            if w.all():
                continue
            src = np.where(chain & w, ar, -1)
            np.maximum.accumulate(src, out=src)
            need = np.flatnonzero(~w)
            prev = src[need]
            ok = prev >= 0
            pose[need[ok], k] = pose[prev[ok], k]
            pose[need[~ok], k] = np.nan
        keep = np.flatnonzero(emit)
        sel = order[keep]
        frame = column("frame", sel)
        # only the frames targets use, in order of first use
        used, first = np.unique(frame[frame >= 0], return_index=True)
        used = used[np.argsort(first)]
        remap = np.full(len(self.frames) + 1, -1, np.int32)
        remap[used] = np.arange(len(used), dtype=np.int32)
        frame = np.where(frame >= 0, remap[frame], -1).astype(np.int32)
        self.frames[:] = [self.frames[k] for k in used]
        self.assumed_robroot = {int(remap[k]) for k in self.assumed_robroot if remap[k] >= 0}
        return Targets(
            poses=pose[keep],
            spans=column("spans", sel).reshape(len(sel), 6, 2)[:, :3],
            abc_spans=column("spans", sel).reshape(len(sel), 6, 2)[:, 3:],
            file=column("file", sel),
            line=column("line", sel),
            col=column("col", sel),
            frame=frame,
            motion=column("motion", sel),
            config=column("config", sel),
        )

    def start_frame(self) -> int:
        return self.frame_index(self.start_state())[0]
