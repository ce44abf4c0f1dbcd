"""``python -m pinn_mpc``: the application's command line (:mod:`pinn_mpc_cli`), run as a
script; no module of the package imports it."""

import sys

from pinn_mpc_cli.cli import main

sys.exit(main())
