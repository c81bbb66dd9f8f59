# Compile the reference engine's ahead-of-time module for this machine (what a one-chain
# run loads instead of numba's JIT), from the signatures the JIT kernels were compiled with.
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
