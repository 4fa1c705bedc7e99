"""The damper FMUs in a railway vehicle: co-simulation, hunting stability, scenario comparison.

* :mod:`tuner.vehicle.cosim`: the 14-DOF vehicle of :mod:`campaign.vehicle` as co-simulation master of four
  yaw damper FMUs (:class:`VehicleCosim`);
* :mod:`tuner.vehicle.hunting`: critical speed by a time-domain speed search, and by eigenvalues;
* :mod:`tuner.vehicle.compare`: the same scenarios with several FMUs side by side
  (``python -m tuner vehicle``).
"""
