"""The identification problem: design variables (``parametrization``), simulation engines through
the FMU or the C kernel (``runner``, ``engine``), the converged reference (``reference``), the
Firefly algorithm (``firefly``), the local solver (``polish``), the pipeline (``fit``) and the
full-rate check of a decimated fit (``full_rate``).
"""
