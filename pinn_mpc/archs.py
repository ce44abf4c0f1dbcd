"""Architecture names, importable without torch (the CLI parses them at start-up)."""

from __future__ import annotations

#: The paper's three architectures.
ARCHS = ("mlp", "physreg", "physnet")
#: Every architecture: the paper's and the hybrid this package recommends for control.
ALL_ARCHS = (*ARCHS, "hybrid")
DEFAULT_ARCH = "hybrid"
