# granchain main workflow: `snakemake --cores 2` runs the `default` preset of
# config/config.yaml (`--config preset=tiny|default|full` picks another) and writes every
# table, trace and figure under results/<preset>/. On a cluster:
#     snakemake --profile workflow/profiles/slurm --config preset=full
# Rules live in workflow/rules/*.smk; each calls the granchain package through a script in
# workflow/scripts/ (logic: granchain/workflow/, tables.py, figures/, thesis/, accuracy/).
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


# Front page of `snakemake --report report.html`.
report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/ensembles.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/lammps.smk"
include: "workflow/rules/accuracy.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/vibrometer.smk"
include: "workflow/rules/inference.smk"


# On a cluster, rules that take a second or two run on the submitting node instead of
# waiting in the queue (gather_study is declared in tables.smk).
localrules:
    all,
    fig5_1a,
    fig5_1b,
    fig5_1c,
    fig5_3b,
    fig5_3c,
    fig5_4b,
    thesis_comparison,
    accuracy_cost_figure,


# Every final output, listed in one place: all_targets() (common.smk).
rule all:
    default_target: True
    input:
        all_targets(),
