# Configuration, the preset's plan, path helpers, and every final target.
# A bad configuration stops here with one message, before any job runs.
# Every rule calls the granchain package through a script (workflow/scripts/*.py).
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from granchain import workflow as gw
from granchain.errors import GranchainError

try:
    validate(config, "../schemas/config.schema.yaml")
except WorkflowError as exc:
    raise WorkflowError(gw.config_error_message(exc)) from None
# The plan: every study's scenes and job batches, built once (granchain.workflow.presetplan);
# batches, trace materials and report captions all come from it.
try:
    PLAN = gw.Plan.build(config)
    # Sizes for the report's captions: tables (describe) and figures (caption_sizes).
    DESCRIBE = {study: gw.describe(PLAN, study) for study in PLAN.studies}
    SIZES = {study: gw.caption_sizes(PLAN, study) for study in PLAN.studies}
except GranchainError as exc:
    raise WorkflowError(str(exc)) from None
PRESET, P = PLAN.name, PLAN.preset

# Everything of a preset lives under results/<preset>/.
RESULTS = f"results/{PRESET}"
FIG_DIR = f"{RESULTS}/figures"
STUDIES = PLAN.studies      # the chapter's, then the optional ones the preset has
# the optional studies the preset has, the field's (precompression, wall) and the chapter's
# questions (radius_spread, dissipation, plasticity, adhesion, capture): each has a figure of its name
OPTIONAL = [s for s in gw.OPTIONAL_STUDIES if s in STUDIES]
FIGURES = ["fig5_1b", "fig5_1c", "fig5_3b", "fig5_3c", "fig5_4b"] + OPTIONAL   # fig5_1a: one per material
BATCH_THREADS = int(P["batch"]["threads"])
BATCH_MEM_MB = int(P["batch"]["mem_mb"])


wildcard_constraints:
    study="|".join(STUDIES),
    index=r"\d+",


def table_path(study):
    """results/<preset>/tables/<study>.csv: one row per member (granchain/tables.py)."""
    return f"{RESULTS}/tables/{study}.csv"


def parquet_path(study):
    """results/<preset>/tables/<study>.parquet: the table's typed Parquet copy, which the
    figures and the thesis comparison read (granchain.tables.read_table)."""
    return f"{RESULTS}/tables/{study}.parquet"


def trace_path(material):
    return f"{RESULTS}/traces/packed_trace_{material}.npz"


def trace_materials():
    return PLAN.materials("packed_trace")


def batch_of(study, engine, index):
    try:
        return PLAN.batch(study, f"{engine}_{index}")
    except GranchainError as exc:
        raise WorkflowError(str(exc)) from None


def batch_outputs(study, suffix=".csv"):
    """The batch tables (suffix .csv) or timings (.timing.csv) a study's gather needs."""
    if study == "packed_trace":
        return [f"{RESULTS}/work/packed_trace/trace{suffix}"]
    return [f"{RESULTS}/work/{study}/{b.name}{suffix}" for b in PLAN.batches[study]]


def batch_runtime(study, engine, index):
    """SLURM wall-clock limit (minutes) of a batch, from its estimated cost, or from its
    cost with every chain at its cap where its laws can hold a chain there
    (``Batch.limit_seconds``)."""
    b = batch_of(study, engine, index)
    return gw.runtime_minutes(max(b.est_seconds, b.limit_seconds), BATCH_THREADS)


# The vibrometer study (optional, vibrometer.smk): its scenes and outputs.
VIB = PLAN.vibrometer
VIB_SPEC = P["studies"].get("vibrometer") or {}


def vib_trace_path(material):
    return f"{RESULTS}/traces/vibrometer_{material}.npz"


def vib_trace_materials():
    return list(dict.fromkeys(ss.material for ss in VIB if ss.gap_mean_nm == 0))


def vibrometer_targets():
    """The vibrometer study's outputs (none without the study)."""
    if not VIB:
        return []
    return [
        f"{RESULTS}/tables/vibrometer.csv",
        f"{RESULTS}/tables/vibrometer.provenance.json",
        f"{RESULTS}/timing/vibrometer.csv",
        *[vib_trace_path(m) for m in vib_trace_materials()],
        *expand(f"{FIG_DIR}/fig5_2a_{{material}}.{{ext}}", material=vib_trace_materials(),
                ext=["png", "pdf"]),
        *expand(f"{FIG_DIR}/vibrometer.{{ext}}", ext=["png", "pdf"]),
    ]


MEAS_DIR = Path(workflow.basedir) / "measurements"
MEASUREMENTS = sorted(p.stem for p in MEAS_DIR.glob("*.csv")) if MEAS_DIR.is_dir() else []


def inference_targets(include_examples=True):
    """results/<preset>/inference/<name>.json and .png for each measurements/<name>.csv
    (inference.smk); without the shipped synthetic examples (example_*) unless asked."""
    names = [m for m in MEASUREMENTS if include_examples or not m.startswith("example_")]
    return [f"{RESULTS}/inference/{m}.{ext}" for m in names for ext in ("json", "png")]


def all_targets():
    """Every final output, which the Snakefile's default target asks for: tables and
    summaries, traces, figures, the engine and thesis comparisons, accuracy vs cost."""
    return [
        *[table_path(s) for s in STUDIES],
        *[parquet_path(s) for s in STUDIES],
        *[f"{RESULTS}/tables/{s}_summary.csv" for s in STUDIES],
        *[trace_path(m) for m in trace_materials()],
        f"{RESULTS}/tables/lammps_vs_reference.csv",
        *expand(f"{FIG_DIR}/fig5_1a_{{material}}.{{ext}}", material=trace_materials(),
                ext=["png", "pdf"]),
        *expand(f"{FIG_DIR}/{{name}}.{{ext}}", name=FIGURES, ext=["png", "pdf"]),
        f"{RESULTS}/tables/thesis_comparison.csv",
        f"{RESULTS}/tables/thesis_comparison.md",
        f"{RESULTS}/tables/accuracy_cost.csv",
        f"{RESULTS}/tables/accuracy_cost.provenance.json",
        f"{RESULTS}/timing/accuracy_cost.csv",
        f"{RESULTS}/timing/accuracy_cost_cheapest.csv",
        f"{FIG_DIR}/accuracy_cost.png",
        f"{FIG_DIR}/accuracy_cost.pdf",
        *vibrometer_targets(),      # vibrometer.smk (none without the study)
        *inference_targets(include_examples=False),   # inference.smk: real measurements only
        f"{RESULTS}/work/aot_kernels.done",           # ensembles.smk: the engine's kernels
    ]
