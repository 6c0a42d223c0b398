"""``python -m rdgpu.cli``: the ``rdgpu`` command."""

import sys

from rdgpu.cli.app import main

sys.exit(main())
