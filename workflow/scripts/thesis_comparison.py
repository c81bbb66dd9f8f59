# The thesis comparison table (CSV and Markdown) from the study tables: granchain.thesis.
# Inputs other than `code` are the tables (and the ss440c trace, if any) by study name.
from granchain import thesis
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    data = {name: path for name, path in snakemake.input.items() if name != "code" and path}
    kw = thesis.read_inputs(data)
    kw["radius"] = snakemake.params.radius
    thesis.write(thesis.comparison(**kw), snakemake.output.csv, snakemake.output.md,
                 snakemake.params.title)
    print(snakemake.output.csv)
    print(snakemake.output.md)
