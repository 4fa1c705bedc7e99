"""Benchmark: cost of one 1 ms communication step of every native FMU, FMI 2.0 and FMI 3.0, from a C host.

    python benchmarks/bench_c_host.py [--seconds 20] [--repeats 7] [--kinds lumped twochamber ...]

A tiny C host (no Python in the loop; compiled here with the system compiler, -O2) dlopens the FMU's
binary (RTLD_LOCAL), instantiates it, initialises it at the stroke's start and steps a 5 Hz, 5 mm
sine for 20 s at 1 ms as a multibody master does: per step it sets stroke and stroke_velocity,
calls doStep and reads the force. The step loop alone is timed with clock_gettime(CLOCK_MONOTONIC)
(instantiation and initialisation excluded). Each FMU runs in its own process; the FMUs are
interleaved repeat by repeat and the median is reported, so machine load hits them alike. The last
force and the sum of the forces are printed too: the FMI 2.0 and 3.0 FMUs of a model must agree to
the last bit (same kernel).
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from damper_fmu.fmu import SLAVES, ensure_fmu, native_reason  # noqa: E402

HOST = r"""
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

typedef void (*logger2_t)(void *, const char *, int, const char *, const char *, ...);
typedef struct { logger2_t log; void *(*alloc)(size_t, size_t); void (*fre)(void *); void *step_finished; void *env; }
    callbacks2;
static void logger2(void *e, const char *n, int s, const char *c, const char *m, ...) {
    (void)e; (void)c; fprintf(stderr, "%s [%d]: %s\n", n, s, m);
}
static void logger3(void *e, int s, const char *c, const char *m) { (void)e; (void)c; fprintf(stderr, "[%d]: %s\n", s, m); }

#define SYM(name) void *name = dlsym(lib, #name); if (!name) { fprintf(stderr, "no %s\n", #name); return 2; }

int main(int argc, char **argv) {
    const char *path, *token;
    int version, k, n;
    double h = 1e-3, seconds, w = 2.0 * 3.141592653589793 * 5.0, force = 0.0, sum = 0.0;
    unsigned int in[2] = {0, 1}, out = 2;
    double u[2];
    struct timespec t0, t1;
    void *lib, *c;
    if (argc < 5) { fprintf(stderr, "usage: host BINARY FMI_VERSION TOKEN SECONDS\n"); return 9; }
    path = argv[1]; version = atoi(argv[2]); token = argv[3]; seconds = atof(argv[4]);
    n = (int)(seconds / h + 0.5);
    lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    u[0] = 0.0; u[1] = 5e-3 * w;
    if (version == 2) {
        typedef void *(*inst_t)(const char *, int, const char *, const char *, const callbacks2 *, int, int);
        typedef int (*setup_t)(void *, int, double, double, int, double);
        typedef int (*mode_t)(void *);
        typedef int (*real_t)(void *, const unsigned int *, size_t, double *);
        typedef int (*step_t)(void *, double, double, int);
        typedef void (*free_t)(void *);
        static callbacks2 cb;
        SYM(fmi2Instantiate) SYM(fmi2SetupExperiment) SYM(fmi2EnterInitializationMode)
        SYM(fmi2ExitInitializationMode) SYM(fmi2SetReal) SYM(fmi2GetReal) SYM(fmi2DoStep) SYM(fmi2FreeInstance)
        real_t set = (real_t)fmi2SetReal, get = (real_t)fmi2GetReal;
        step_t step = (step_t)fmi2DoStep;
        cb.log = logger2; cb.alloc = calloc; cb.fre = free;
        c = ((inst_t)fmi2Instantiate)("bench", 1 /* fmi2CoSimulation */, token, "", &cb, 0, 0);
        if (!c) return 3;
        ((setup_t)fmi2SetupExperiment)(c, 0, 0.0, 0.0, 0, 0.0);
        ((mode_t)fmi2EnterInitializationMode)(c);
        set(c, in, 2, u);
        if (((mode_t)fmi2ExitInitializationMode)(c) != 0) return 4;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (k = 0; k < n; k++) {
            double t = k * h;
            u[0] = 5e-3 * sin(w * t); u[1] = 5e-3 * w * cos(w * t);
            set(c, in, 2, u);
            if (step(c, t, h, 1) != 0) return 5;
            get(c, &out, 1, &force);
            sum += force;
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        ((free_t)fmi2FreeInstance)(c);
    } else {
        /* fmi3Boolean is C's bool */
        typedef void *(*inst_t)(const char *, const char *, const char *, bool, bool, bool, bool, const unsigned int *,
                                size_t, void *, void (*)(void *, int, const char *, const char *), void *);
        typedef int (*enter_t)(void *, bool, double, double, bool, double);
        typedef int (*mode_t)(void *);
        typedef int (*get_t)(void *, const unsigned int *, size_t, double *, size_t);
        typedef int (*set_t)(void *, const unsigned int *, size_t, const double *, size_t);
        typedef int (*step_t)(void *, double, double, bool, bool *, bool *, bool *, double *);
        typedef void (*free_t)(void *);
        bool ev, term, early;
        double last;
        SYM(fmi3InstantiateCoSimulation) SYM(fmi3EnterInitializationMode) SYM(fmi3ExitInitializationMode)
        SYM(fmi3SetFloat64) SYM(fmi3GetFloat64) SYM(fmi3DoStep) SYM(fmi3FreeInstance)
        set_t set = (set_t)fmi3SetFloat64;
        get_t get = (get_t)fmi3GetFloat64;
        step_t step = (step_t)fmi3DoStep;
        c = ((inst_t)fmi3InstantiateCoSimulation)("bench", token, "", 0, 0, 0, 0, NULL, 0, NULL, logger3, NULL);
        if (!c) return 3;
        ((enter_t)fmi3EnterInitializationMode)(c, 0, 0.0, 0.0, 0, 0.0);
        set(c, in, 2, u, 2);
        if (((mode_t)fmi3ExitInitializationMode)(c) != 0) return 4;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (k = 0; k < n; k++) {
            double t = k * h;
            u[0] = 5e-3 * sin(w * t); u[1] = 5e-3 * w * cos(w * t);
            set(c, in, 2, u, 2);
            if (step(c, t, h, 1, &ev, &term, &early, &last) != 0) return 5;
            get(c, &out, 1, &force, 1);
            sum += force;
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        ((free_t)fmi3FreeInstance)(c);
    }
    printf("%.6f %.17g %.17g\n", ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / 1e3 / n, force, sum);
    return 0;
}
"""


def compile_host(tmp: Path) -> Path:
    from damper_fmu.native import compiler

    cc = compiler()
    src = tmp / "host.c"
    src.write_text(HOST)
    exe = tmp / "host"
    subprocess.run([cc, "-O2", "-std=c99", str(src), "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def unpack(fmu: Path, dest: Path) -> tuple[Path, str]:
    """(binary for this platform, instantiation token / GUID) of the FMU at ``fmu``."""
    from fmpy import read_model_description

    with zipfile.ZipFile(fmu) as z:
        z.extractall(dest)
    binary = next(p for p in (dest / "binaries").rglob("*") if p.suffix in (".so", ".dylib", ".dll"))
    return binary, read_model_description(str(fmu)).guid


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="simulated time per run [s] (1 ms steps)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--kinds", nargs="+", default=list(SLAVES), choices=list(SLAVES))
    args = ap.parse_args(argv)
    if native_reason():
        print(f"no native FMUs here: {native_reason()}")
        return 1
    if shutil.which("uptime"):
        print("load:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
    variants = [(kind, v) for kind in args.kinds for v in (2, 3)]
    with tempfile.TemporaryDirectory(prefix="bench_c_host_") as tmp:
        tmp = Path(tmp)
        host = compile_host(tmp)
        runs = {}
        for kind, v in variants:
            fmu = ensure_fmu(kind, flavour="native", fmi_version=v)
            runs[kind, v] = (fmu.name, *unpack(fmu, tmp / f"{kind}{v}"))
        times = {key: [] for key in variants}
        results = {}
        for _ in range(args.repeats):
            for key in variants:
                name, binary, token = runs[key]
                proc = subprocess.run([str(host), str(binary), str(key[1]), token, str(args.seconds)],
                                      capture_output=True, text=True)
                if proc.returncode != 0:
                    print(f"{name}: host failed ({proc.returncode}): {proc.stderr.strip()}")
                    return 1
                us, last, total = proc.stdout.split()
                times[key].append(float(us))
                results[key] = (last, total)
    n = int(args.seconds / 1e-3 + 0.5)
    print(f"us per 1 ms communication step from a C host ({n} steps of a 5 Hz, 5 mm sine; median of "
          f"{args.repeats}, min in brackets):")
    print(f"  {'model':<14} {'FMI 2.0':>18} {'FMI 3.0':>18}   forces FMI 2.0 == FMI 3.0")
    for kind in args.kinds:
        cells = [f"{statistics.median(times[kind, v]):8.3f} ({min(times[kind, v]):6.3f})" for v in (2, 3)]
        same = "yes (bit for bit)" if results[kind, 2] == results[kind, 3] else f"NO: {results[kind, 2]} {results[kind, 3]}"
        print(f"  {kind:<14} {cells[0]:>18} {cells[1]:>18}   {same}")
    return 0 if all(results[k, 2] == results[k, 3] for k in args.kinds) else 1


if __name__ == "__main__":
    sys.exit(main())
