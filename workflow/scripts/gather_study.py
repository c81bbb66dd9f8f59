# A study's batch tables -> table (CSV and Parquet), summary, provenance, timing.
# Logic: granchain.workflow.gather.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    gw.set_threads(snakemake.threads)
    name, preset = gw.select_preset(snakemake.config)
    gw.gather(name, preset, snakemake.wildcards.study, snakemake.input.batches,
              snakemake.input.timings, snakemake.output.table, snakemake.output.summary,
              snakemake.output.provenance, snakemake.output.timing,
              snakemake.output.parquet)
