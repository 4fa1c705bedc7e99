"""The damper's datasheet: the characteristics suppliers and vehicle engineers exchange, from a damper FMU
driven by sine strokes as a co-simulation master drives it, and from a rig's own sine tests.

- ``loop``: what is read off one settled sine loop (first harmonics, K', K'', loss angle, equivalent Maxwell k
  and c, harmonic distortion, the forces at peak velocity), the same for a simulated and a measured loop;
- ``sine_runs``: a damper FMU driven through fmpy by sine strokes until the loop has settled (``SineDriver``);
- ``characteristic``: the simulated force-velocity and dynamic characteristics of one FMU and its series stiffness;
- ``measured``: the measured points of a rig's sine tests and the model's at the same frequency and amplitude;
- ``nominal``: a supplier's nominal force-velocity characteristic with its tolerance band, and which points lie in it;
- ``sheet``: the datasheet of several FMUs as one record, ``datasheet.json`` and the CSV tables a multibody code takes.
"""
