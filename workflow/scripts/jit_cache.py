# Compile the reference engine's kernels for this machine once, before the jobs that use
# them (granchain.engines.backend.build); the output records that it ran.
import time

from granchain import workflow as gw
from granchain.engines import backend, warmup

with gw.log_to(snakemake.log[0]):
    t0 = time.perf_counter()
    warmup.build()
    with open(snakemake.output[0], "w") as fh:
        fh.write(f"kernels {backend.module_name()} ready in {time.perf_counter() - t0:.1f} s\n")
