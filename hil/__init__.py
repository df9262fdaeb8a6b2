"""The loop and the product surface: scheduler, safety supervisor, experiments, logs, CLI."""

import os

# One BLAS thread: the loop's matrices are small (12 joints: at most 48 x 48), where a thread
# pool costs more than it saves, and on a busy machine much more (measured on 2 shared cores:
# a 72 x 72 triangular solve 18.9 ms with OpenBLAS's threads, 0.46 ms with one). Set before
# numpy is first imported; a value the user set stays.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
