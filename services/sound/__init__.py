"""The sound service: impacts in, modal (or sampled, or synthesised) drum sound out at 48 kHz."""

import os

# Each block's BLAS work is a few small matrix products (16 x 2K @ 2K x 16): extra BLAS threads only add wake-up
# and spin time, and on a busy machine a ringing china then took 100+ ms per 5.3 ms block instead of 1 ms. Set
# before NumPy loads BLAS (the sound commands import this package first); a value the user set is kept.
for _variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
