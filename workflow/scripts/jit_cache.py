# Compile the reference engine's JIT kernels for this machine once, before the jobs that
# use them (granchain.engines.warmup, in the rule's threads as processes at once); the
# output records that it ran. The ahead-of-time module follows in aot_kernels, which no
# job waits for.
import time

from granchain import workflow as gw
from granchain.engines import backend, warmup

with gw.log_to(snakemake.log[0]):
    t0 = time.perf_counter()
    warmup.build(workers=snakemake.threads, aot=False)
    with open(snakemake.output[0], "w") as fh:
        fh.write(f"JIT kernels of {backend.module_name()} ready in "
                 f"{time.perf_counter() - t0:.1f} s\n")
