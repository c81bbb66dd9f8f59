# Figures (the chapter's panels) and the thesis comparison table, drawn from the contract's
# tables and traces. Logic: granchain/figures/ (figures.render, through
# scripts/figure.py) and granchain/thesis/ (scripts/thesis_comparison.py), both built on
# granchain/reductions/. Every output
# goes into the report (`snakemake --report report.html`) with a caption from
# workflow/report/ (rendered with this preset's sizes, SIZES in common.smk).

# The drawing code is an input: a changed figure module redraws (the tables stay).
REDUCTIONS_CODE = sorted(
    str(p) for p in (Path(workflow.basedir) / "granchain" / "reductions").glob("*.py"))
FIG_CODE = REDUCTIONS_CODE + sorted(
    str(p) for p in (Path(workflow.basedir) / "granchain" / "figures").glob("*.py"))
THESIS_CODE = REDUCTIONS_CODE + sorted(
    str(p) for p in (Path(workflow.basedir) / "granchain" / "thesis").rglob("*.py"))


rule fig5_1a:
    input:
        trace=trace_path("{material}"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_1a_{{material}}.png",
            caption="../report/fig5_1a.rst",
            category="Figures",
            subcategory="5.1 packed chain",
            labels={"figure": "5.1a", "material": "{material}"},
        ),
        pdf=f"{FIG_DIR}/fig5_1a_{{material}}.pdf",
    params:
        figure="fig5_1a",
        sizes=SIZES["packed_trace"],
    log:
        f"{RESULTS}/logs/figures/fig5_1a_{{material}}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


rule fig5_1b:
    input:
        packed_sweep=parquet_path("packed_sweep"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_1b.png",
            caption="../report/fig5_1b.rst",
            category="Figures",
            subcategory="5.1 packed chain",
            labels={"figure": "5.1b", "material": "all"},
        ),
        pdf=f"{FIG_DIR}/fig5_1b.pdf",
    params:
        figure="fig5_1b",
        sizes=SIZES["packed_sweep"],
    log:
        f"{RESULTS}/logs/figures/fig5_1b.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


rule fig5_1c:
    input:
        packed_sweep=parquet_path("packed_sweep"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_1c.png",
            caption="../report/fig5_1c.rst",
            category="Figures",
            subcategory="5.1 packed chain",
            labels={"figure": "5.1c", "material": "all"},
        ),
        pdf=f"{FIG_DIR}/fig5_1c.pdf",
    params:
        figure="fig5_1c",
        sizes=SIZES["packed_sweep"],
    log:
        f"{RESULTS}/logs/figures/fig5_1c.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


rule fig5_3b:
    input:
        gap_profile=parquet_path("gap_profile"),
        packed_sweep=parquet_path("packed_sweep"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_3b.png",
            caption="../report/fig5_3b.rst",
            category="Figures",
            subcategory="5.3 gaps",
            labels={"figure": "5.3b", "material": P["studies"]["gap_profile"]["material"]},
        ),
        pdf=f"{FIG_DIR}/fig5_3b.pdf",
    params:
        figure="fig5_3b",
        sizes=SIZES["gap_profile"],
    log:
        f"{RESULTS}/logs/figures/fig5_3b.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


rule fig5_3c:
    input:
        gap_sweep=parquet_path("gap_sweep"),
        packed_sweep=parquet_path("packed_sweep"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_3c.png",
            caption="../report/fig5_3c.rst",
            category="Figures",
            subcategory="5.3 gaps",
            labels={"figure": "5.3c", "material": "all"},
        ),
        pdf=f"{FIG_DIR}/fig5_3c.pdf",
    params:
        figure="fig5_3c",
        radius=P["base"]["radius"],
        sizes=SIZES["gap_sweep"],
    log:
        f"{RESULTS}/logs/figures/fig5_3c.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


rule fig5_4b:
    input:
        extra_length=parquet_path("extra_length"),
        packed_sweep=parquet_path("packed_sweep"),
        code=FIG_CODE,
    output:
        png=report(
            f"{FIG_DIR}/fig5_4b.png",
            caption="../report/fig5_4b.rst",
            category="Figures",
            subcategory="5.4 loose chains",
            labels={"figure": "5.4b", "material": "all"},
        ),
        pdf=f"{FIG_DIR}/fig5_4b.pdf",
    params:
        figure="fig5_4b",
        radius=P["base"]["radius"],
        sizes=SIZES["extra_length"],
    log:
        f"{RESULTS}/logs/figures/fig5_4b.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/figure.py"


# The optional studies (beyond the chapter), when the preset has them: one figure each,
# named as the study, from its table (granchain/figures/field.py: the field's chains,
# granchain/figures/questions.py: the chapter's questions).
for _study in OPTIONAL:

    rule:
        name:
            f"{_study}_figure"
        input:
            **{_study: parquet_path(_study)},
            code=FIG_CODE,
        output:
            png=report(
                f"{FIG_DIR}/{_study}.png",
                caption=f"../report/{_study}.rst",
                category="Figures",
                subcategory="beyond the chapter",
                labels={"figure": _study, "material": "all"},
            ),
            pdf=f"{FIG_DIR}/{_study}.pdf",
        params:
            figure=_study,
            radius=P["base"]["radius"],
            sizes=SIZES[_study],
        log:
            f"{RESULTS}/logs/figures/{_study}.log",
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        localrule: True
        conda:
            "../envs/granchain.yaml"
        script:
            "../scripts/figure.py"


rule thesis_comparison:
    input:
        packed_sweep=parquet_path("packed_sweep"),
        packed_trace=parquet_path("packed_trace"),
        gap_profile=parquet_path("gap_profile"),
        gap_sweep=parquet_path("gap_sweep"),
        extra_length=parquet_path("extra_length"),
        trace=trace_path("ss440c") if "ss440c" in trace_materials() else [],
        vibrometer=f"{RESULTS}/tables/vibrometer.csv" if PLAN.vibrometer else [],
        precompression=parquet_path("precompression") if "precompression" in OPTIONAL else [],
        wall=parquet_path("wall") if "wall" in OPTIONAL else [],
        radius_spread=parquet_path("radius_spread") if "radius_spread" in OPTIONAL else [],
        dissipation=parquet_path("dissipation") if "dissipation" in OPTIONAL else [],
        plasticity=parquet_path("plasticity") if "plasticity" in OPTIONAL else [],
        adhesion=parquet_path("adhesion") if "adhesion" in OPTIONAL else [],
        capture=parquet_path("capture") if "capture" in OPTIONAL else [],
        code=THESIS_CODE,
    output:
        csv=report(
            f"{RESULTS}/tables/thesis_comparison.csv",
            caption="../report/thesis_comparison.rst",
            category="Tables",
            subcategory="thesis comparison",
            labels={"table": "thesis_comparison", "kind": "chapter vs this project"},
        ),
        md=report(
            f"{RESULTS}/tables/thesis_comparison.md",
            caption="../report/thesis_comparison.rst",
            category="Tables",
            subcategory="thesis comparison",
            labels={"table": "thesis_comparison (Markdown)", "kind": "chapter vs this project"},
        ),
    params:
        radius=P["base"]["radius"],
        title=f"Thesis comparison (preset {PRESET})",
        sizes={"preset": PRESET},
    log:
        f"{RESULTS}/logs/figures/thesis_comparison.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/granchain.yaml"
    script:
        "../scripts/thesis_comparison.py"
