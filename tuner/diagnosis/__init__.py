"""What the fitted model gets wrong and why: residual evidence (``residuals``), confidence
intervals (``significance``), candidate refits, forward selection and the verdict (``diagnose``).
"""
