# One of the chapter's figures (PNG and PDF) from the tables or a trace: granchain.figures.
# Inputs other than `code` are the figure's data, by the name render() expects.
from granchain import figures
from granchain import workflow as gw

with gw.log_to(snakemake.log[0]):
    data = {name: path for name, path in snakemake.input.items() if name != "code"}
    for path in figures.render(snakemake.params.figure, data, snakemake.output.png,
                               radius=snakemake.params.get("radius")):
        print(path)
