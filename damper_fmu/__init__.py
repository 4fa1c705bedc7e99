"""Railway hydraulic damper models as plain Python (no FMI here).

SI units throughout. Sign convention: stroke x1 [m] positive in extension, stroke
velocity v1 [m/s] its time derivative, force [N] positive in tension (the damper
pulls its end mounts together while it is being extended).
"""
