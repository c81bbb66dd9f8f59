# Compile the reference engine's ahead-of-time module for this machine (what every call of
# the engine runs, serial or in forked processes), from the types the warm-up runs call the
# entry points with, its parts in the rule's threads as processes at once; without
# numba.pycc, numba's JIT kernels.
import time

from granchain import workflow as gw
from granchain.engines import backend, warmup

with gw.log_to(snakemake.log[0]):
    t0 = time.perf_counter()
    path = warmup.build(workers=snakemake.threads)
    with open(snakemake.output[0], "w") as fh:
        fh.write(f"ahead-of-time kernels {backend.module_name()}: "
                 f"{path if path is not None else 'not built (numba.pycc unavailable)'} "
                 f"in {time.perf_counter() - t0:.1f} s\n")
