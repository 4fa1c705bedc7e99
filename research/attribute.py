import json, sys, time
from pathlib import Path
from research.variants import make
from research.common import load, base_fit, rmse_sets
seed = int(sys.argv[1])
names = sys.argv[2].split(",")
res_file = Path(f"/tmp/form/attribution_s{seed}.json")
res = json.loads(res_file.read_text()) if res_file.exists() else {}
for v in names:
    t0 = time.time()
    folder = Path(f"/tmp/form/var_{v}_s{seed}")
    try:
        make(v, seed, folder)
    except Exception as e:
        print(v, "generation failed", e, flush=True); continue
    tg = time.time() - t0
    d = load(folder)
    base, el = base_fit(d, Path(f"/tmp/form/fit_{v}_s{seed}"), log=lambda m: None)
    rid, rval = rmse_sets("lumped", base, d)
    res[v] = {"id": rid, "val": rval, "noise": d["noise"], "gen_s": tg, "fit_s": el}
    Path(f"/tmp/form/fit_{v}_s{seed}/base_params.json").write_text(json.dumps(base))
    print(f"{v:22s} id {rid:7.1f} N ({rid/d['noise']:5.1f}x)  val {rval:7.1f} N ({rval/d['noise']:5.1f}x)  noise {d['noise']:.1f}  gen {tg:.0f}s fit {el:.0f}s", flush=True)
    res_file.write_text(json.dumps(res, indent=1))
