# packed_trace: each material's row and its v(t) trace (.npz). Logic: granchain.workflow.run.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    gw.set_threads(snakemake.threads)
    _, preset = gw.select_preset(snakemake.config)
    gw.run_traces(preset, dict(zip(snakemake.params.materials, snakemake.output.traces)),
                  snakemake.output.table, snakemake.output.timing, snakemake.threads)
