# Accuracy vs cost of every integration setting: `granchain.accuracy measure`.
import os

# numba reads its thread count when it is first imported: set it to the job's threads first.
os.environ["NUMBA_NUM_THREADS"] = str(snakemake.threads)

import sys  # noqa: E402

from granchain import accuracy  # noqa: E402
from granchain import workflow as gw  # noqa: E402

out = snakemake.output
with gw.log_to(snakemake.log[0]):
    rc = accuracy.main(["measure", "--preset", snakemake.params.preset,
                    "--cost-json", snakemake.params.cost, "--base-json", snakemake.params.base,
                    "--table", out.table, "--provenance", out.provenance,
                    "--timing", out.timing, "--cheapest", out.cheapest])
if rc:
    sys.exit(rc)
