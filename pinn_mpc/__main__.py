import sys

from pinn_mpc.cli import main

sys.exit(main())
