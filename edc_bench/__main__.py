"""``python -m edc_bench`` runs the CLI."""

import sys

from edc_bench.cli import main

sys.exit(main())
