"""Virtual test campaign: vehicle manoeuvres -> damper strokes -> virtual rig -> measured force files.

It never imports the tuner; the tuner uses its vehicle (``tuner.vehicle``) and its generator.

- ``track``: design track geometry (straights, clothoids, constant curves, the S-curve switch);
- ``irregularity``: lateral track irregularity from the ERRI B176 PSD;
- ``vehicle``: the linear lateral/yaw model of one high-speed car with Maxwell yaw dampers;
- ``contact``: nonlinear wheel-rail contact of a wheelset: conicity, flange dead band, saturating creep;
- ``vehicle_nonlinear``: the same car with that contact on straight track, for hunting limit cycles;
- ``bifurcation``: hunting limit cycles against speed by ramp-down, nonlinear critical speed, conicity sweep;
- ``periodic_orbits``: limit cycles by shooting, stable or unstable, continued in amplitude through the fold;
- ``contact_table``: the tabulated S1002-on-UIC60 contact geometry against the wheelset's lateral displacement;
- ``cooperrider``: the DTU group's full Cooperrider car (body, two frames, four wheelsets) on that contact;
- ``cooperrider_params``: its parameters, read from DYTSI's input file, with the ones DYTSI fixes in its source;
- ``cooperrider_runs``: its hunting runs (batches of speeds), growth rates, cycles and critical speeds;
- ``scenarios``: the six manoeuvres of the paper's Table 1 and the front-right yaw damper's stroke [m];
- ``rig``: the virtual damper test rig (stroke imposed, force and stroke recorded);
- ``rig_damper``: the rig's physically based twin-tube damper (the "real" damper);
- ``effects``: the switchable hidden effects and forms of the rig damper;
- ``sensors``: the sensor chain (noise, anti-alias filter, decimation, ADC);
- ``programme``: a damper test programme in one run (a stepped sine of several frequencies and amplitudes);
- ``synthetic``: datasets written by one of the damper models itself, with known parameters;
- ``damper_class``: random dampers of each model's class, for the convergence benchmark;
- ``rig_class``: random physical twin-tube dampers and their rig tests with faults hidden in the damper or the rig
  chain, for the blind benchmark on the physical damper;
- ``plots``: the overview figure of a dataset folder;
- ``generate``: the campaign end to end, scenarios -> strokes -> rig -> dataset folder;
- ``cli``: its command line (``python -m campaign generate``, also ``python -m tuner generate``);
- ``__main__``: ``python -m campaign``.
"""
