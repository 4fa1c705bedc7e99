"""Command-line plumbing: exit handling shared by the commands (``run``) and fleets (``batch``);
the commands themselves are in ``tuner.__main__``.
"""
