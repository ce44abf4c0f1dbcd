"""``python -m pinn_mpc``: runs the installed ``pinn-mpc`` command, found by its console-script
entry point in the distribution's metadata, so the modelling package names no module above it
(the command line is :mod:`pinn_mpc_cli`, which ``python -m pinn_mpc_cli`` runs directly)."""

import sys
from importlib.metadata import entry_points

found = entry_points(group="console_scripts", name="pinn-mpc")
if not found:
    sys.exit(
        "python -m pinn_mpc: error: the pinn-mpc command is not installed (no `pinn-mpc` "
        "console script); install the package (pip install -e .), or run python -m pinn_mpc_cli"
    )
sys.exit(next(iter(found)).load()())
