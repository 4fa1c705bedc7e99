"""Our Cooperrider car (campaign.cooperrider) beside DYTSI, the DTU railway vehicle simulator, on the
same parameters and S1002/UIC60 contact table: linear critical speed on straight track and the
limit-cycle amplitude 5 % above it, side by side.

    python benchmarks/dytsi_cooperrider.py [--reference ../shared/reference/dytsi] [--build /work/dytsi-build]
                                           [--dt 5e-4] [--around 3] [--cycle-time 120] [--nonlinear --start TEST:SPEED --v-low 60]

DYTSI (LGPL-3.0) is never part of the project: this script copies its source from ``--reference``
into ``--build`` (outside the repository) and builds it there as the reference README says (Debian's
GSL, Xerces-C and Boost; ``make -j2``), or uses the build it finds there; it then runs the published
straight-track case (``inputBifurcation-Cooperrider-straight.xml``: 20..160 m/s in 1 m/s steps, 10 s
per speed from a 0.1 mm offset of the leading wheelset; 15-40 min on 2 shared cores) unless its
output is complete already, and parses ``input/Output/Cooperrider/<test>/output.dat``.

Printed: for DYTSI and ours, the growth rate of the leading wheelset's response at the speeds around
the change from decay to growth, the bracket and the interpolated linear critical speed; our
eigenvalue critical speed, and the hunting eigenvalue of DYTSI's own Jacobian stored at the end of
each speed beside ours at equilibrium (alike where DYTSI's state has decayed to equilibrium); the
limit-cycle amplitude at 1.05 x DYTSI's critical speed (a longer run of both, ``--cycle-time``);
with ``--nonlinear`` the speed where the cycle disappears when the speed is stepped down (DYTSI:
its bifurcation run from the cycle, each speed from the last state; ours the same); and the numbers
``tests/test_cooperrider.py`` holds (GSL's cubic spline of the table at a few points, DYTSI's
response at 1 s, its contact forces at one stored state).
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from campaign.contact_table import ContactTableError, read_contact_table  # noqa: E402
from campaign.cooperrider import N_STATES, CooperriderCar, state_index  # noqa: E402
from campaign.cooperrider_params import read_cooperrider_xml  # noqa: E402
from campaign.cooperrider_runs import (cycle_amplitude, equilibrium, jacobian, linear_critical_speed,  # noqa: E402
                                       offset_state, run_speeds, sweep_result)

REPO = Path(__file__).resolve().parents[1]
STRAIGHT = "InputFiles/inputBifurcation-Cooperrider-straight.xml"
COMPONENTS = ("Car Body[ID 0]", "Leading Bogie Frame[ID 1]", "Trailing Bogie Frame[ID 2]",
              "Leading Bogie - Leading Wheelset[ID 3]", "Leading Bogie - Trailing Wheelset[ID 4]",
              "Trailing Bogie - Leading Wheelset[ID 5]", "Trailing Bogie - Trailing Wheelset[ID 6]")
FRAME_DOFS = ("Y", "YDOT", "Z", "ZDOT", "PHI", "PHIDOT", "CHI", "CHIDOT", "PSI", "PSIDOT")
WHEELSET_DOFS = ("Y", "YDOT", "Z", "ZDOT", "PHI", "PHIDOT", "BETA", "PSI", "PSIDOT")
LEADING_Y = f"{COMPONENTS[3]}::Y"


def dytsi_order() -> np.ndarray:
    """Our state index of each of DYTSI's 66 states, in DYTSI's order (car body, bogie frames, then
    the wheelsets; names :data:`FRAME_DOFS` / :data:`WHEELSET_DOFS`)."""
    order = []
    for body in range(7):
        for name in (FRAME_DOFS if body < 3 else WHEELSET_DOFS):
            coord = name.removesuffix("DOT").lower()
            order.append(state_index(body, coord, rate=name.endswith("DOT") and coord != "beta"))
    return np.array(order)


def find_or_build(reference: Path, build: Path) -> Path:
    """DYTSI's binary in ``build``; copied and built there (README's recipe) when missing."""
    src = build / "dytsi"
    binary = src / "build" / "src" / "DYTSI"
    if binary.exists():
        return binary
    if not (reference / "src" / "Models" / "CooperriderOrthogonalModel.cpp").exists():
        sys.exit(f"no DYTSI source at {reference} (--reference): cannot build the reference engine")
    build.mkdir(parents=True, exist_ok=True)
    shutil.copytree(reference, src, dirs_exist_ok=True)
    for path in src.rglob("*"):
        path.chmod(path.stat().st_mode | 0o200)
    (src / "compat.h").write_text("#include <cmath>\nusing std::isnan;\nusing std::isinf;\n")
    (src / "build").mkdir(exist_ok=True)
    flags = f"CXXFLAGS=-O2 -Dxercesc_3_1=xercesc_3_2 -fpermissive -w -include {src / 'compat.h'}"
    for cmd, cwd in ((["autoreconf", "-fi"], src), (["../configure", flags], src / "build"),
                     (["make", "-j2"], src / "build")):
        print("  $", " ".join(cmd), flush=True)
        done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
        if done.returncode:
            sys.exit(f"building DYTSI failed at {' '.join(cmd)}:\n{done.stderr[-3000:]}\n(apt-get install -y "
                     "libgsl-dev libxerces-c-dev libboost-filesystem-dev libboost-system-dev autoconf automake libtool)")
    return binary


def dytsi_version(binary: Path) -> str:
    out = subprocess.run([str(binary)], capture_output=True, text=True).stdout
    match = re.search(r"DYTSI version \S+", out)
    return match.group(0) if match else "DYTSI (version line not found)"


def run_dytsi(binary: Path, xml: Path, rerun: bool = False) -> Path:
    """Run DYTSI on ``xml`` (inside its ``input/`` folder) unless its output exists already (and
    ``rerun`` is False); return the test's output folder."""
    input_dir = binary.parents[2] / "input"
    root = ET.parse(xml).getroot()
    test = root[0].get("TestName")
    out_dir = input_dir / root.get("OutputFolder") / test
    out = out_dir / "output.dat"
    if out.exists() and not rerun:
        print(f"  DYTSI output found, reused (last speed {_last_speed(out)} m/s; --rerun to run again): {out}")
        return out_dir
    cmd = [str(binary), "-T", "-nt", str(xml.relative_to(input_dir) if xml.is_relative_to(input_dir) else xml)]
    print(f"  $ (cd {input_dir} && {' '.join(cmd)})", flush=True)
    t0 = time.time()
    log = out_dir.parent / f"{test}.log"
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "w") as fh:
        done = subprocess.run(cmd, cwd=input_dir, stdout=fh, stderr=subprocess.STDOUT)
    if done.returncode or not out.exists():
        sys.exit(f"DYTSI failed (exit {done.returncode}); its log: {log}")
    print(f"  DYTSI ran {time.time() - t0:.0f} s")
    return out_dir


def _last_speed(out: Path) -> float | None:
    with open(out, "rb") as fh:
        fh.seek(max(0, out.stat().st_size - 20000))
        lines = fh.read().decode(errors="replace").strip().splitlines()
    try:
        return float(lines[-1].split("\t")[3])
    except (IndexError, ValueError):
        return None


def read_dytsi_output(out: Path, t_end: float) -> dict:
    """Per segment of DYTSI's ``output.dat``: speed [m/s], times 0..``t_end`` [s] (the stored
    0.01 s grid) and the 66 states in our layout (nt, 66). Returns {"speeds", "t", "states",
    "rows"} with states (n_speeds, nt, 66) and rows the raw header->index map."""
    order = dytsi_order()
    with open(out) as fh:
        header = [h.strip('"') for h in fh.readline().rstrip("\n").split("\t")]
        cols = [header.index(f"{c}::{d}") for b, c in enumerate(COMPONENTS)
                for d in (FRAME_DOFS if b < 3 else WHEELSET_DOFS)]
        segments: dict = {}
        for line in fh:
            f = line.split("\t")
            t = float(f[1])
            if t > t_end + 1e-9:
                continue
            seg = segments.setdefault(int(float(f[0])), {"v": float(f[3]), "rows": {}})
            seg["rows"][round(t * 100)] = [float(f[c]) for c in cols]
    n_t = int(round(t_end * 100)) + 1
    speeds, states = [], []
    for seg in segments.values():
        if len(seg["rows"]) < n_t:
            continue                                            # segment still running
        x = np.zeros((n_t, N_STATES))
        x[:, order] = np.array([seg["rows"][k] for k in range(n_t)])
        speeds.append(seg["v"])
        states.append(x)
    return {"speeds": np.array(speeds), "t": np.arange(n_t) / 100.0, "states": np.array(states),
            "header": {h: i for i, h in enumerate(header)}}


HUNTING_BAND = (20.0, 40.0)
"""Angular frequencies [rad/s] of the car's hunting family (the oscillation is about 4.7 Hz)."""


def band_eigenvalue(J: np.ndarray) -> complex:
    """The eigenvalue [1/s] of ``J`` with the largest real part among those with an imaginary part in
    :data:`HUNTING_BAND`: the hunting mode's."""
    ev = np.linalg.eigvals(J)
    band = ev[(ev.imag > HUNTING_BAND[0]) & (ev.imag < HUNTING_BAND[1])]
    return complex(band[np.argmax(band.real)])


def dytsi_jacobian(out_dir: Path, segment: int) -> np.ndarray | None:
    """DYTSI's own Jacobian (66, 66), in our state layout, stored at the end of segment ``segment``
    (1-based file ``Jacobians/jac-<segment>.dat``, 6 significant digits), or None."""
    path = out_dir / "Jacobians" / f"jac-{segment}.dat"
    if not path.exists():
        return None
    order = dytsi_order()
    J = np.zeros((N_STATES, N_STATES))
    J[np.ix_(order, order)] = np.loadtxt(path)
    return J


def ours_jacobian(params, table, speed: float) -> np.ndarray:
    car = CooperriderCar(params, table, float(speed))
    return jacobian(car, equilibrium(car))


GSL_PROGRAM = r"""
#include <stdio.h>
#include <stdlib.h>
#include <gsl/gsl_interp.h>
/* natural cubic spline (gsl_interp_cspline) of one column of an RSGEO table, as DYTSI interpolates it */
int main(int argc, char** argv) {
  FILE* f = fopen(argv[1], "r"); int col = atoi(argv[2]); char line[4096]; int n = 0, cap = 8192;
  double *x = malloc(cap * sizeof(double)), *y = malloc(cap * sizeof(double)), v[13];
  fgets(line, sizeof line, f); fgets(line, sizeof line, f);
  while (fgets(line, sizeof line, f)) {
    if (sscanf(line, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf", v, v+1, v+2, v+3, v+4, v+5, v+6,
               v+7, v+8, v+9, v+10, v+11, v+12) != 13) break;
    x[n] = v[0]; y[n] = v[col]; n++;
  }
  gsl_interp* s = gsl_interp_alloc(gsl_interp_cspline, n); gsl_interp_init(s, x, y, n);
  gsl_interp_accel* acc = gsl_interp_accel_alloc();
  for (int k = 3; k < argc; k++) printf("%.17g\n", gsl_interp_eval(s, x, y, atof(argv[k]), acc));
  return 0;
}
"""


def gsl_spline_values(build: Path, table: Path, column: int, points) -> list:
    """GSL's natural cubic spline (DYTSI's ``cspline``) of ``column`` of ``table`` at ``points`` [m],
    by a small C program compiled against the GSL that DYTSI links."""
    exe = build / "gsl_cspline"
    if not exe.exists():
        (build / "gsl_cspline.c").write_text(GSL_PROGRAM)
        subprocess.run(["cc", "-O2", "-o", str(exe), str(build / "gsl_cspline.c"), "-lgsl", "-lgslcblas", "-lm"],
                       check=True)
    out = subprocess.run([str(exe), str(table), str(column)] + [repr(p) for p in points], capture_output=True,
                         text=True, check=True).stdout
    return [float(v) for v in out.split()]


def print_sweep(name: str, sweep, extra: dict | None = None) -> None:
    print(f"  {name}: speed [m/s] -> growth rate of the leading wheelset's response [1/s], end amplitude [mm]")
    for j, v in enumerate(sweep.speeds):
        note = f"   {extra[v]}" if extra and v in extra else ""
        print(f"    {v:7.2f}  {sweep.growth[j]:+9.4f}  {1e3 * sweep.amplitude[j]:8.4f}{note}")
    print(f"    bracket {sweep.bracket}, linear critical speed (interpolated) {sweep.critical_speed}")


VALUE_ELEMENTS = ("CarBodyValues", "LeadingBogieFrameValues", "TrailingBogieFrameValues", "LLWheelSetValues",
                  "LTWheelSetValues", "TLWheelSetValues", "TTWheelSetValues")


def write_run_xml(base: Path, out: Path, test: str, speeds: tuple, t_end: float, start: np.ndarray | None) -> Path:
    """A copy of DYTSI input ``base`` with test name ``test``, SpeedRange ``(first, last, step)``
    [m/s], TSpan 0..``t_end`` [s] and, if ``start`` (66,) in our layout is given, those starting
    values for the first speed, each later speed starting from the last state of the one before."""
    tree = ET.parse(base)
    bif = tree.getroot()[0]
    bif.set("TestName", test)
    rng = bif.find("SpeedRange")
    for tag, value in zip(("StartValue", "EndValue", "StepSize"), speeds):
        rng.find(tag).text = repr(float(value))
    bif.find("TSpan/EndValue").text = repr(float(t_end))
    if start is not None:
        sv = bif.find("StartingValues")
        sv.set("type", "first")
        for body, name in enumerate(VALUE_ELEMENTS):
            node = sv.find(f".//{name}")
            for child in node:
                coord = child.tag.removesuffix("DOT").lower()
                rate = child.tag.endswith("DOT")
                child.text = repr(float(start[state_index(body, coord, rate=rate and coord != "beta")]))
    tree.write(out, xml_declaration=True, encoding="ISO-8859-1")
    return out


def ours_sweep(params, table, speeds, args, offset: float = 1e-4) -> object:
    """Our responses at ``speeds`` from an ``offset`` [m] of the leading wheelset, 10 s, as one batch."""
    t0 = time.time()
    run = run_speeds(params, table, speeds, offset_state(offset, m=len(speeds)), 10.0, dt=args.dt)
    print(f"  ours: {len(speeds)} speeds x 10 s in {time.time() - t0:.0f} s (RK4, dt {args.dt} s)")
    return sweep_result(run.speeds, run.t, run.signal())


def cycle_both(binary, xml, params, table, speed, args) -> dict:
    """Leading wheelset's limit-cycle amplitude [m] of DYTSI and ours at ``speed``: half the
    peak-to-peak value over the last ``args.window`` s of ``args.cycle_time`` s from the 0.1 mm
    offset, and over the window before (convergence)."""
    test = f"02-Cycle-{speed:.2f}-{args.cycle_time:.0f}s"
    run_xml = write_run_xml(xml, xml.parent / f"{test}.xml", test, (speed, speed, 1.0), args.cycle_time, None)
    out_dir = run_dytsi(binary, run_xml, args.rerun)
    d = read_dytsi_output(out_dir / "output.dat", args.cycle_time)
    yd = d["states"][0][:, state_index(3, "y")]
    t0 = time.time()
    ours = run_speeds(params, table, [speed], offset_state(), args.cycle_time, dt=args.dt)
    print(f"  ours: {args.cycle_time} s at {speed:.2f} m/s in {time.time() - t0:.0f} s")
    yo = ours.signal()[:, 0]
    t, w = d["t"], args.window
    early = t <= t[-1] - w
    return {"speed": speed, "dytsi": cycle_amplitude(t, yd, w), "ours": cycle_amplitude(t, yo, w),
            "dytsi_before": cycle_amplitude(t[early], yd[early], w),
            "ours_before": cycle_amplitude(t[early], yo[early], w)}


def step_down(binary, xml, params, table, args) -> dict:
    """Both cars stepped down from a large cycle of DYTSI: the end state of its segment at the speed
    of ``args.start`` (``TEST:SPEED``, a DYTSI output folder of this build and a speed it ran; both
    cars start from that same state), by ``args.step`` m/s to ``args.v_low``, 10 s per speed, each
    from the last state of the speed before; the amplitude [m] over the last 2 s of each speed and the
    nonlinear critical speed: the lowest speed whose amplitude stays above 1 mm (below, the response
    leaves the large cycle)."""
    test_from, _, speed_from = args.start.partition(":")
    src = read_dytsi_output(binary.parents[2] / "input" / "Output" / "Cooperrider" / test_from / "output.dat", 10.0)
    j = int(np.argmin(np.abs(src["speeds"] - float(speed_from))))
    top, start = float(src["speeds"][j]), src["states"][j][-1]
    print(f"  from DYTSI's state at the end of {top} m/s of {test_from} (leading wheelset "
          f"{1e3 * start[state_index(3, 'y')]:.3f} mm)")
    speeds = np.arange(top - args.step, args.v_low - 1e-9, -args.step)
    test = f"03-StepDown-{top:.0f}-{args.v_low:.0f}-{args.step:g}"
    run_xml = write_run_xml(xml, xml.parent / f"{test}.xml", test, (speeds[0], speeds[-1], -args.step), 10.0, start)
    out_dir = run_dytsi(binary, run_xml, args.rerun)
    d = read_dytsi_output(out_dir / "output.dat", 10.0)
    amp_d = {float(v): cycle_amplitude(d["t"], x[:, state_index(3, "y")]) for v, x in zip(d["speeds"], d["states"])}
    x = start
    amp_o = {}
    t0 = time.time()
    for v in speeds:
        try:
            run = run_speeds(params, table, [v], x, 10.0, dt=args.dt)
        except ContactTableError as exc:
            print(f"  ours at {v} m/s: {exc}")
            break
        amp_o[float(v)] = cycle_amplitude(run.t, run.signal()[:, 0])
        x = run.final[:, 0]
        if amp_o[float(v)] < 1e-4:
            break
    print(f"  ours: step-down in {time.time() - t0:.0f} s")
    return {"dytsi": amp_d, "ours": amp_o, "dytsi_fold": _fold(amp_d), "ours_fold": _fold(amp_o)}


def _fold(amplitudes: dict) -> float | None:
    """Lowest speed of the run down from the cycle before the amplitude falls below 1 mm."""
    last = None
    for v in sorted(amplitudes, reverse=True):
        if amplitudes[v] < 1e-3:
            return last
        last = v
    return None


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", type=Path, default=REPO.parent / "shared" / "reference" / "dytsi",
                    help="DYTSI's published source and inputs (read-only)")
    ap.add_argument("--build", type=Path, default=Path("/work/dytsi-build"),
                    help="where DYTSI is copied, built and run (outside the repository)")
    ap.add_argument("--dt", type=float, default=5e-4, help="our RK4 step [s]")
    ap.add_argument("--around", type=int, default=3, help="speeds on each side of DYTSI's bracket we also run")
    ap.add_argument("--cycle-time", type=float, default=120.0, help="run time for the limit cycle [s] (0: leave the cycle out)")
    ap.add_argument("--window", type=float, default=10.0,
                    help="the cycle amplitude is half the peak-to-peak value over this last time [s]")
    ap.add_argument("--rerun", action="store_true", help="run DYTSI again even where its output exists")
    ap.add_argument("--nonlinear", action="store_true", help="also step down from the cycle")
    ap.add_argument("--small-offset", type=float, default=0.0,
                    help="also run ours from this offset [m] (e.g. 1e-7: towards the eigenvalues' limit)")
    ap.add_argument("--start", default="01-BifurcationUp-Straight:130",
                    help="TEST:SPEED, DYTSI's output and segment whose end state starts the step-down")
    ap.add_argument("--step", type=float, default=2.0, help="speed step of the step-down [m/s]")
    ap.add_argument("--v-low", type=float, default=60.0, help="lowest speed of the step-down [m/s]")
    return ap.parse_args(argv)


def linear_part(binary, xml, out_dir, params, table, args) -> tuple:
    """Both linear critical speeds (time domain and eigenvalues), printed side by side."""
    data = read_dytsi_output(out_dir / "output.dat", 10.0)
    iy = state_index(3, "y")
    dytsi = sweep_result(data["speeds"], data["t"], data["states"][:, :, iy].T)
    if dytsi.bracket is None:
        sys.exit(f"DYTSI's response never turns from decay to growth over {data['speeds'][[0, -1]]} m/s")
    lo, hi = dytsi.bracket
    grid = data["speeds"]
    near = grid[(grid >= lo - args.around) & (grid <= hi + args.around)]
    index = {float(v): j for j, v in enumerate(grid)}
    jac_d = {float(v): dytsi_jacobian(out_dir, index[float(v)] + 1) for v in near}
    eig_d = {v: None if J is None else band_eigenvalue(J) for v, J in jac_d.items()}
    eig_o = {float(v): band_eigenvalue(ours_jacobian(params, table, float(v))) for v in near}
    notes = {v: f"hunting eigenvalue: DYTSI's Jacobian at 10 s {_ev(eig_d[v])}, ours at equilibrium {_ev(eig_o[v])}"
             for v in eig_d}
    near_idx = [index[float(v)] for v in near]
    sub = sweep_result(near, data["t"], data["states"][near_idx][:, :, iy].T)
    print_sweep("DYTSI", sub, notes)
    ours = ours_sweep(params, table, near, args)
    print_sweep("ours", ours)
    v_eig = linear_critical_speed(params, table, float(near[0]), float(near[-1]))
    print(f"  ours from the eigenvalues of the linearised car: {v_eig:.3f} m/s")
    if args.small_offset:
        tiny = ours_sweep(params, table, near, args, offset=args.small_offset)
        print_sweep(f"ours from a {args.small_offset:g} m offset (the contact's small-amplitude limit)", tiny)
    return dytsi, ours, v_eig, data


def _ev(z) -> str:
    return "-" if z is None else f"{z.real:+.4f}{z.imag:+.3f}j"


def test_numbers(build, table_path, data, version) -> None:
    """The numbers tests/test_cooperrider.py holds: DYTSI's leading wheelset at 1 s of one speed."""
    print(f"\nFor tests/test_cooperrider.py ({version}; GSL cspline by gsl_spline_values):")
    pts = [0.0, 1.234e-3, -5.6789e-3, 8.0005e-3, 1.69999e-2]
    for col, name in ((1, "N"), (2, "angle"), (3, "a"), (6, "rw"), (8, "c22")):
        print(f"  GSL {name}: {gsl_spline_values(build, table_path, col, pts)}")
    iy = state_index(3, "y")
    for v in (105.0, 110.0):
        j = int(np.argmin(np.abs(data["speeds"] - v)))
        print(f"  DYTSI {data['speeds'][j]} m/s, leading wheelset y at t = 0.1, 0.5, 1.0 s: "
              f"{[float(data['states'][j][k, iy]) for k in (10, 50, 100)]}")


def main(argv=None) -> None:
    args = parse_args(argv)
    print("Building or finding DYTSI")
    binary = find_or_build(args.reference.resolve(), args.build.resolve())
    version = dytsi_version(binary)
    print(f"  {binary}: {version}")
    xml = binary.parents[2] / "input" / STRAIGHT
    out_dir = run_dytsi(binary, xml, args.rerun)
    model = read_cooperrider_xml(args.reference / "input" / STRAIGHT, input_dir=args.reference / "input")
    table = read_contact_table(model.table_path)
    print(f"Ours: parameters from {args.reference / 'input' / STRAIGHT}, table {model.table_path}")
    print("\nLinear critical speed on straight track (0.1 mm offset of the leading wheelset, 10 s per speed)")
    dytsi, ours, v_eig, data = linear_part(binary, xml, out_dir, model.params, table, args)
    v_cr = dytsi.critical_speed
    speed = round(1.05 * v_cr, 2)
    cyc = None
    if args.cycle_time > 0:
        print(f"\nLimit cycle at 1.05 x DYTSI's critical speed = {speed} m/s, {args.cycle_time} s from the offset")
        cyc = cycle_both(binary, xml, model.params, table, speed, args)
    print("\nSide by side                               DYTSI        ours      ours/DYTSI")
    print(f"  linear critical speed (time) [m/s]   {v_cr:10.3f}  {ours.critical_speed:10.3f}  "
          f"{ours.critical_speed / v_cr:10.4f}")
    print(f"  linear critical speed (eigen) [m/s]  {'':10s}  {v_eig:10.3f}  {v_eig / v_cr:10.4f}")
    if cyc is not None:
        print(f"  cycle amplitude at {speed} m/s [mm] {1e3 * cyc['dytsi']:10.5f}  {1e3 * cyc['ours']:10.5f}  "
              f"{cyc['ours'] / cyc['dytsi']:10.5f}")
        print(f"    (the {args.window:g} s before: DYTSI {1e3 * cyc['dytsi_before']:.4f} mm, ours "
              f"{1e3 * cyc['ours_before']:.4f} mm)")
    if args.nonlinear:
        down = step_down(binary, xml, model.params, table, args)
        print("\nStep-down from the cycle: speed [m/s] -> end amplitude [mm], DYTSI / ours")
        for v in sorted(set(down["dytsi"]) | set(down["ours"]), reverse=True):
            print(f"    {v:7.2f}  {1e3 * down['dytsi'].get(v, np.nan):8.4f}  {1e3 * down['ours'].get(v, np.nan):8.4f}")
        print(f"  nonlinear critical speed [m/s]: DYTSI {down['dytsi_fold']}, ours {down['ours_fold']}")
    test_numbers(args.build.resolve(), model.table_path, data, version)


if __name__ == "__main__":
    main()
