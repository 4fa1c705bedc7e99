"""The damper FMUs in a railway vehicle: co-simulation, hunting stability, scenario comparison.

- ``cosim``: the 14-DOF vehicle of ``campaign.vehicle`` as co-simulation master of four yaw damper
  FMUs (``VehicleCosim``; its master loop in C, ``c/vehicle_master.c``);
- ``hunting``: the critical speed [m/s] by a time-domain speed search, and by eigenvalues;
- ``nonlinear_cosim``: the nonlinear car of ``campaign.vehicle_nonlinear`` (saturating creep, flange) with four
  yaw damper FMUs, Runge-Kutta within each communication step (``NonlinearCosim``);
- ``limit_cycles``: per FMU and wheel conicity the linear and nonlinear critical speeds and the bifurcation
  diagrams, side by side (``python -m tuner vehicle --nonlinear``);
- ``cooperrider_cosim``: DTU's Cooperrider car on tabulated S1002/UIC60 contact (``campaign.cooperrider``) with
  four yaw damper FMUs per speed, several speeds per batch (``CooperriderCosim``);
- ``cooperrider_hunting``: its linear critical speed and limit cycle per FMU beside its own D6 dashpots
  (``python -m tuner vehicle --cooperrider``, ``cooperrider.json``);
- ``compare``: the same scenarios with several FMUs side by side (``python -m tuner vehicle``);
- ``propagation``: the identification's parameter uncertainty carried to the critical speed and the curve's
  peak damper force (95 % intervals from parameter sets drawn from the fitted covariance).
"""
