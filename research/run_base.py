import json, sys, time
from pathlib import Path
from research.common import load, base_fit, rmse_sets
folder, out = Path(sys.argv[1]), Path(sys.argv[2])
d = load(folder)
print("noise", d["noise"], flush=True)
base, el = base_fit(d, out, log=lambda m: print(m, flush=True))
rid, rval = rmse_sets("lumped", base, d)
print(f"RESULT base id {rid:.1f} N val {rval:.1f} N noise {d['noise']:.2f} -> {rid/d['noise']:.1f}x / {rval/d['noise']:.1f}x  fit {el:.0f} s")
(out / "base_params.json").write_text(json.dumps(base, indent=1))
(out / "base_result.json").write_text(json.dumps({"id": rid, "val": rval, "noise": d["noise"], "elapsed": el}))
