# Compile the reference engine's ahead-of-time module for this machine (what every call
# that runs no chains in parallel loads instead of numba's JIT), from the types the warm-up
# runs call the entry points with; without numba.pycc, numba's JIT kernels in one process.
import time

from granchain import workflow as gw
from granchain.engines import backend, warmup

with gw.log_to(snakemake.log[0]):
    t0 = time.perf_counter()
    path = warmup.build()
    with open(snakemake.output[0], "w") as fh:
        fh.write(f"ahead-of-time kernels {backend.module_name()}: "
                 f"{path if path is not None else 'not built (numba.pycc unavailable)'} "
                 f"in {time.perf_counter() - t0:.1f} s\n")
