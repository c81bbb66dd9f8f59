# Error against wall time per chain, log-log: `granchain.accuracy figure`.
import sys

from granchain import accuracy
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    rc = accuracy.main(["figure", snakemake.input.timing, snakemake.output.png,
                    snakemake.output.pdf])
if rc:
    sys.exit(rc)
