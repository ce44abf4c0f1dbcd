import sys

from pinn_mpc_cli.cli import main

sys.exit(main())
