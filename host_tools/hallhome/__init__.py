"""hallhome host toolkit: robot model, field model, table generator, serial client."""

import os

# One BLAS thread unless the user asks for more. The toolkit's matrices are
# small (a fit's Jacobian is about 20000 x 33): OpenBLAS's threads cost more
# than they give. Measured on two busy cores, an SVD of 20000 x 33 took 0.045 s
# on one thread and 0.93 s on two, and a fit 36 s against 56 s, with the same
# result to the last digit. It must be set before numpy loads OpenBLAS, so the
# package sets it on import; tests/conftest.py and bench/run.py import the
# package first.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from hallhome.paths import project_version  # noqa: E402

__version__ = project_version()
