# The vibrometer study: each chain simulated once, recorded with every instrument setting.
# Logic: granchain.workflow.vibrometer.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    name, preset = gw.select_preset(snakemake.config)
    gw.write_vibrometer(name, preset, snakemake.output.table, snakemake.output.provenance,
                        snakemake.output.timing,
                        dict(zip(snakemake.params.materials, snakemake.output.traces)))
