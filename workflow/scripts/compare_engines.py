# LAMMPS vs reference on the lammps_check scenes. Logic: granchain.workflow.lammps_check.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    gw.set_threads(snakemake.threads)
    name, preset = gw.select_preset(snakemake.config)
    gw.write_engine_comparison(name, preset, snakemake.output.table,
                               snakemake.output.provenance, snakemake.threads)
