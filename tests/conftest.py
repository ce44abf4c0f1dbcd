"""Test-session set-up: one BLAS and one torch thread per process.

The suite runs with ``-n 2`` on 2 cores; a second BLAS/torch thread per worker oversubscribes the
machine and makes small linear algebra many times slower.
"""

import torch
from threadpoolctl import threadpool_limits

threadpool_limits(limits=1)
torch.set_num_threads(1)
