"""brakethermo — offline carbon brake-disc thermal estimation from race telemetry."""

import os

# Small banded solves batched over sigma points are slower with a threaded BLAS
# (thread start-up dominates); pin to one thread unless the user asked otherwise.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

__all__ = ["__version__"]
