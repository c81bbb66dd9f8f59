# Compile the reference engine's JIT kernels for this machine once, before the jobs on more
# than one thread that use them (granchain.engines.warmup, in the rule's threads as
# processes at once; the laws come from numba's cache, where aot_kernels compiled them);
# the output records that it ran.
import time

from granchain import workflow as gw
from granchain.engines import backend, warmup

with gw.log_to(snakemake.log[0]):
    t0 = time.perf_counter()
    warmup.build(workers=snakemake.threads, aot=False, jit=True)
    with open(snakemake.output[0], "w") as fh:
        fh.write(f"JIT kernels of {backend.module_name()} ready in "
                 f"{time.perf_counter() - t0:.1f} s\n")
