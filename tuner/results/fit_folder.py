"""What the fit report reads: a fit output folder (``FitFolder``: parameters.json, metrics.json,
history_<model>.json, simulations.npz; SI units)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from damper_fmu.parameters import MODEL_PARAMETERS, defaults
from tuner.results.html import MODEL_ORDER
from tuner import strict_json


__all__ = ["FitFolder", "read_json", "ordered_models"]

def read_json(path: Path, required: bool):
    if not path.exists():
        if required:
            raise ValueError(f"fit output is incomplete: {path.name} not found in {path.parent}")
        return None
    try:
        return strict_json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path} is not valid JSON: {exc}") from exc


def ordered_models(names) -> list[str]:
    names = list(names)
    return [m for m in MODEL_ORDER if m in names] + sorted(m for m in names if m not in MODEL_ORDER)


class FitFolder:
    """Everything read from one fit output folder."""

    def __init__(self, out: Path):
        if not out.is_dir():
            raise ValueError(f"fit output folder {out} does not exist")
        self.out = out
        self.params = read_json(out / "parameters.json", True)
        self.metrics = read_json(out / "metrics.json", True)
        for key in ("tests",):
            if key not in self.metrics:
                raise ValueError(f"metrics.json has no '{key}' entry")
        self.settings = self.metrics.get("settings", {}) or {}
        self.tests = self.metrics["tests"]
        self.table3 = self.metrics.get("table3", {}) or {}
        names = set(self.params)
        for t in self.tests.values():
            names.update(t.get("models", {}))
        self.models = ordered_models(names)
        self.histories = {m: read_json(out / f"history_{m}.json", False) for m in self.models}
        self.validation = [n for n, t in self.tests.items() if t.get("role") == "validation"]
        self.identification = [n for n, t in self.tests.items() if t.get("role") != "validation"]
        self.warmup = float(self.settings.get("warmup_s", 0.0) or 0.0)
        self.sims = None
        npz = out / "simulations.npz"
        if npz.exists():
            with np.load(npz) as z:
                self.sims = {k: np.asarray(z[k], dtype=float) for k in z.files}

    def series(self, test: str):
        """(time [s], stroke [m], measured force [N], {model: simulated force [N]}) or None."""
        if self.sims is None or f"{test}__time" not in self.sims:
            return None
        t, x, f = (self.sims.get(f"{test}__{k}") for k in ("time", "stroke", "force"))
        if x is None or f is None:
            return None
        sim = {m: self.sims[f"{test}__{m}"] for m in self.models if f"{test}__{m}" in self.sims}
        for name, a in [("stroke", x), ("force", f), *sim.items()]:
            if a.shape != t.shape:
                raise ValueError(f"simulations.npz: {test}__{name} has {a.size} samples, "
                                 f"{test}__time has {t.size}")
        return t, x, f, sim

    def values(self, model: str) -> dict:
        """Identified values of ``model`` completed with the preset (fixed abscissae) [SI]."""
        v = defaults(model) if model in MODEL_PARAMETERS else {}
        v.update((self.params.get(model) or {}).get("values", {}))
        return v
