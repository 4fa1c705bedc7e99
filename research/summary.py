"""Print the result tables of the form research from /tmp/form/*.json."""
import json
from pathlib import Path

import sys
F = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/form")


def show(path, title):
    if not path.exists():
        return
    print(f"\n## {title} ({path.name})")
    for k, r in json.loads(path.read_text()).items():
        n = r["noise"]
        extra = ""
        if "params" in r:
            p = r["params"]
            extra = "  " + " ".join(f"{q}={p[q]:.4g}" for q in ("kR", "kC", "a", "kM", "cM", "LR", "LC", "air", "fres", "kgas", "ffric", "ffric_out", "mass") if q in p)
            extra += f"  n_params={r['n_params']}"
        elif "extra" in r:
            extra = "  " + " ".join(f"{q}={v:.4g}" for q, v in r["extra"].items())
        t = r.get("elapsed_s", r.get("fit_s", 0.0))
        print(f"{k:34s} id {r['id']:7.1f} N {r['id'] / n:6.1f}x   held-out {r['val']:7.1f} N {r['val'] / n:6.1f}x   {t:5.0f} s{extra}")


show(F / "attribution_s1.json", "attribution, seed 1: tuner base lumped fit on the twin-tube with a mechanism switched off")
show(F / "attribution_s2.json", "attribution, seed 2")
show(F / "cand_s1.json", "lumped chain + add-on elements, seed 1")
show(F / "tc_results_s1.json", "two-chamber form, seed 1")
show(F / "tc_results_s2.json", "two-chamber form, seed 2")
show(F / "attribution_s3.json", "tuner base, seed 3")
show(F / "tc_results_s3.json", "two-chamber form, seed 3")
show(F / "tc_lumped_s1.json", "two-chamber form on the LUMPED damper (seed 1)")
show(F / "tc_effects_s1.json", "hidden effects on the twin-tube, seed 1")
show(F / "tc_effects_s2.json", "hidden effects on the twin-tube, seed 2")
