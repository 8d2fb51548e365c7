"""``python -m nirl_mj.cli``: the same as the ``nirl-mj`` command."""

import sys

from nirl_mj.cli import main

sys.exit(main())
