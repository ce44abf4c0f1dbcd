"""The application: the ``pinn-mpc`` command line, above the three packages it drives
(:mod:`pinn_mpc`, :mod:`controllers`, :mod:`scenarios`); see :mod:`pinn_mpc_cli.cli`."""

from __future__ import annotations

from pinn_mpc_cli.cli import MAX_DAYS, build_parser, main

__all__ = ["MAX_DAYS", "build_parser", "main"]
