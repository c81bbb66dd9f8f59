# LAMMPS vs reference on the lammps_check members. Logic: granchain.workflow / compare.
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    name, preset = gw.select_preset(snakemake.config)
    gw.write_engine_comparison(name, preset, snakemake.input[0], snakemake.output.table,
                               snakemake.output.provenance)
