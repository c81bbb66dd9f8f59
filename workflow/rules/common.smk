# Configuration, preset, plan of jobs, and the names every rule file shares.
# A bad configuration stops here with one message, before any job runs.
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from granchain import workflow as gw
from granchain.errors import GranchainError

try:
    validate(config, "../schemas/config.schema.yaml")
except WorkflowError as exc:
    raise WorkflowError(gw.config_error_message(exc)) from None
try:
    PRESET, P = gw.check_config(config)
except GranchainError as exc:
    raise WorkflowError(str(exc)) from None

# Everything of a preset lives under results/<preset>/.
RESULTS = f"results/{PRESET}"
# Final outputs of every rule file; `rule all` (Snakefile) asks for all of them.
ALL_TARGETS = []

STUDIES = gw.STUDIES
# Job batches of every study: {study: [Batch, ...]} (granchain.workflow.batches).
PLAN = gw.plan(P)
BATCH_THREADS = int(P["batch"]["threads"])
BATCH_MEM_MB = int(P["batch"]["mem_mb"])


wildcard_constraints:
    study="|".join(STUDIES),
    index=r"\d+",


def table_path(study):
    """results/<preset>/tables/<study>.csv: one row per member (granchain/tables.py)."""
    return f"{RESULTS}/tables/{study}.csv"


def trace_path(material):
    return f"{RESULTS}/traces/packed_trace_{material}.npz"


def trace_materials():
    return [ss.material for ss in gw.study_scenes(P, "packed_trace")]


def batch_of(study, engine, index):
    name = f"{engine}_{index}"
    for b in PLAN[study]:
        if b.name == name:
            return b
    raise WorkflowError(f"study {study} has no batch {name} in preset {PRESET}")


def batch_outputs(study, suffix=".csv"):
    """The batch tables (suffix .csv) or timings (.timing.csv) a study's gather needs."""
    if study == "packed_trace":
        return [f"{RESULTS}/work/packed_trace/trace{suffix}"]
    return [f"{RESULTS}/work/{study}/{b.name}{suffix}" for b in PLAN[study]]


def batch_runtime(study, engine, index):
    """SLURM wall-clock limit (minutes) of a batch, from its estimated cost."""
    return gw.runtime_minutes(batch_of(study, engine, index).est_seconds, BATCH_THREADS)
