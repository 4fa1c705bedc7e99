"""How a command-line handler ends: its exit status, and a clear message instead of a traceback.

Exit status: the handler's own; 2 for bad input or arguments (ValueError, including DataError, and
file errors: message on stderr); 1 when a stage of the diagnosis failed (``DiagnosisFailed``: what was
finished is written, the message says where and how to continue); 130 when interrupted (with how to
continue).
"""
from __future__ import annotations

import sys

from tuner.diagnosis.diagnose import DiagnosisFailed

__all__ = ["run_handler"]


def run_handler(handler, args, continue_hint: str) -> int:
    """Run ``handler(args)``; ``continue_hint`` says how to continue after an interruption."""
    try:
        return handler(args)
    except DiagnosisFailed as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"\ninterrupted: {continue_hint}", file=sys.stderr)
        return 130
    except (ValueError, FileExistsError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
