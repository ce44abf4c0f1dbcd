"""pinn-mpc: physics-informed neural network models of buildings, and control with them."""

__version__ = "0.1.0"
