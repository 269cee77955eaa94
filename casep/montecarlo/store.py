"""``out``: the campaign folder, and resuming from it.

Each finished task's runs are written as one Parquet part of ``runs.parquet/`` (columns run,
method, coefficient, estimate, std, true, crlb_std and each run's dispersion draws
``draw_<parameter>``), under a temporary name and then renamed, so a part is whole or absent;
``settings.json`` beside it holds the campaign's settings, ``state.json`` the finished parts.
A rerun with the same settings reads the finished parts back (:meth:`Store.load`) and runs only
the rest; other settings are refused, naming the innermost key that differs.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from casep.io._atomic import atomic_open

__all__ = ["Store", "settings_diff"]

_PART = "part-s{stage:02d}-t{task:05d}.parquet"


def settings_diff(old: Any, new: Any, path: str = "") -> str:
    """What differs between two settings, down to the innermost key (``dispersions.launch_azimuth_deg.high:
    2 there, 3 now``), values cut at 80 characters."""
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        keys = [k for k in dict.fromkeys([*old, *new]) if old.get(k) != new.get(k)]
        return "; ".join(settings_diff(old.get(k), new.get(k), f"{path}.{k}" if path else str(k)) for k in keys)
    return f"{path}: {json.dumps(old)[:80]} there, {json.dumps(new)[:80]} now"


class Store:
    """``--out DIR``: settings.json, runs.parquet/ (one part per finished task), state.json, summary.json."""

    def __init__(self, out: str | os.PathLike, settings: dict) -> None:
        self.dir = Path(out)
        self.parts = self.dir / "runs.parquet"
        sfile = self.dir / "settings.json"
        if sfile.exists():
            old = json.loads(sfile.read_text(encoding="utf-8"))
            if old != settings:
                raise ValueError(f"--out {self.dir}: holds a campaign with other settings "
                                 f"({settings_diff(old, settings)});"
                                 " use another folder, or the same settings to resume")
        else:
            self.dir.mkdir(parents=True, exist_ok=True)
            with atomic_open(sfile) as fh:
                fh.write(json.dumps(settings, indent=2) + "\n")
        self.parts.mkdir(exist_ok=True)
        self.finished: list[str] = []

    def load(self, stage: int, task: int, methods: Sequence[str], names: Sequence[str]) -> dict | None:
        """A finished task's results, read back from its part (None: not finished)."""
        import pyarrow.parquet as pq

        path = self.parts / _PART.format(stage=stage, task=task)
        if not path.exists():
            return None
        tab = pq.read_table(path)
        n = len(names)
        runs_col = tab.column("run").to_numpy()
        m = len(runs_col) // (n * len(methods))
        res: dict[str, Any] = {"runs": runs_col[: m * n: n].astype(np.int64), "est": {}, "std": {}}
        res["truth"] = tab.column("true").to_numpy()[: m * n].reshape(m, n)
        res["crlb"] = tab.column("crlb_std").to_numpy()[: m * n].reshape(m, n)
        res["draws"] = {c.removeprefix("draw_"): tab.column(c).to_numpy()[: m * n: n] for c in tab.column_names
                        if c.startswith("draw_")}
        for i, meth in enumerate(methods):
            sl = slice(i * m * n, (i + 1) * m * n)
            res["est"][meth] = tab.column("estimate").to_numpy()[sl].reshape(m, n)
            sd = tab.column("std").slice(sl.start, m * n)
            res["std"][meth] = None if sd.null_count == m * n else sd.to_numpy(zero_copy_only=False).reshape(m, n)
        self.finished.append(path.name)
        return res

    def save(self, stage: int, task: int, methods: Sequence[str], names: Sequence[str], res: dict) -> None:
        """Write a task's part atomically (temporary name, then renamed), then state.json."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        m, n = len(res["runs"]), len(names)
        k = len(methods)
        est = np.concatenate([res["est"][meth].reshape(-1) for meth in methods])
        sds = [pa.nulls(m * n, pa.float64()) if res["std"][meth] is None else pa.array(res["std"][meth].reshape(-1))
               for meth in methods]
        tab = pa.table({
            "run": np.tile(np.repeat(res["runs"], n), k),
            "method": pa.array(np.repeat(np.array(methods, dtype=object), m * n).tolist(), pa.string()),
            "coefficient": pa.array(np.tile(np.array(names, dtype=object), m * k).tolist(), pa.string()),
            "estimate": est,
            "std": pa.concat_arrays(sds),
            "true": np.tile(res["truth"].reshape(-1), k),
            "crlb_std": np.tile(res["crlb"].reshape(-1), k),
            # each run's dispersion draws (natural units of casep.simulation.dispersions), on every row of the run
            **{f"draw_{p}": np.tile(np.repeat(np.asarray(v, dtype=float), n), k)
               for p, v in res.get("draws", {}).items()},
        })
        name = _PART.format(stage=stage, task=task)
        tmp = self.parts / f".{name}.tmp"
        pq.write_table(tab, tmp)
        os.replace(tmp, self.parts / name)
        self.finished.append(name)
        with atomic_open(self.dir / "state.json") as fh:
            fh.write(json.dumps({"finished_tasks": sorted(self.finished)}, indent=1) + "\n")
