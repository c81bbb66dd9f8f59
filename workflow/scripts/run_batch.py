# One batch of a study (one engine): its rows and timings. Logic: granchain.workflow.run.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    gw.set_threads(snakemake.threads)
    _, preset = gw.select_preset(snakemake.config)
    gw.write_batch(preset, snakemake.params.study, snakemake.params.name,
                   snakemake.output.table, snakemake.output.timing, snakemake.threads)
