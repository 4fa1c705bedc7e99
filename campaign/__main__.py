"""``python -m campaign generate --out DIR``: see ``campaign.cli``."""
import sys

from campaign.cli import main

sys.exit(main())
