# The vibrometer study (optional: a preset's studies.vibrometer): the chapter's laser
# vibrometers on simulated chains. One job simulates each chain once and records it with
# every filter x bandwidth (granchain.workflow.vibrometer): tables/vibrometer.csv (true and
# recorded v_max,1, v_max,2, dt per chain and instrument setting), its provenance, timing,
# and traces/vibrometer_<material>.npz (the packed chain near 0.1 m/s, true and recorded).
# Figures: fig5_2a (true against recorded velocities, Fig. 5.2a counterpart) and
# vibrometer (recorded / true against bandwidth).
import json


if VIB:

    localrules:
        fig5_2a,
        vibrometer_figure,

    rule vibrometer:
        input:
            rules.aot_kernels.output,
        output:
            table=report(
                f"{RESULTS}/tables/vibrometer.csv",
                caption="../report/vibrometer_table.rst",
                category="Tables",
                subcategory="vibrometer",
                labels={"table": "vibrometer", "kind": "true vs recorded, per setting"},
            ),
            provenance=f"{RESULTS}/tables/vibrometer.provenance.json",
            timing=f"{RESULTS}/timing/vibrometer.csv",
            traces=[vib_trace_path(m) for m in vib_trace_materials()],
        params:
            scenes=[ss.scene.hash for ss in VIB],
            sizes=gw.vibrometer_sizes(PLAN),
            instrument=json.dumps(VIB_SPEC, sort_keys=True),
            materials=vib_trace_materials(),
        log:
            f"{RESULTS}/logs/vibrometer/vibrometer.log",
        threads: 1
        resources:
            mem_mb=BATCH_MEM_MB,
            runtime=gw.runtime_minutes(sum(gw.realisation_cost(ss, "reference") * ss.scene.realisations
                                           for ss in VIB)),
        conda:
            "../envs/granchain.yaml"
        script:
            "../scripts/vibrometer.py"

    rule fig5_2a:
        input:
            vibrometer_trace=vib_trace_path("{material}"),
            code=FIG_CODE,
        output:
            png=report(
                f"{FIG_DIR}/fig5_2a_{{material}}.png",
                caption="../report/fig5_2a.rst",
                category="Figures",
                subcategory="5.2 vibrometer",
                labels={"figure": "5.2a", "material": "{material}"},
            ),
            pdf=f"{FIG_DIR}/fig5_2a_{{material}}.pdf",
        params:
            figure="fig5_2a",
            sizes=gw.vibrometer_sizes(PLAN),
        log:
            f"{RESULTS}/logs/figures/fig5_2a_{{material}}.log",
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        conda:
            "../envs/granchain.yaml"
        script:
            "../scripts/figure.py"

    rule vibrometer_figure:
        input:
            vibrometer=f"{RESULTS}/tables/vibrometer.csv",
            code=FIG_CODE,
        output:
            png=report(
                f"{FIG_DIR}/vibrometer.png",
                caption="../report/vibrometer.rst",
                category="Figures",
                subcategory="5.2 vibrometer",
                labels={"figure": "vibrometer", "material": "all"},
            ),
            pdf=f"{FIG_DIR}/vibrometer.pdf",
        params:
            figure="vibrometer",
            sizes=gw.vibrometer_sizes(PLAN),
        log:
            f"{RESULTS}/logs/figures/vibrometer.log",
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        conda:
            "../envs/granchain.yaml"
        script:
            "../scripts/figure.py"
