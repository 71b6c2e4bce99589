# The study's outputs (paper section 6): Tables 1-3, the class statistics, Figures 3-5 and a
# fit figure per vehicle and model order; captions for `snakemake --report` in workflow/report.


rule fit_figure:
    input:
        series="results/vehicles/{vehicle}/identify/{model}_series.csv",
        fit="results/vehicles/{vehicle}/fit_{model}.yaml",
    output:
        png=report(
            "results/vehicles/{vehicle}/fit_{model}.png",
            caption="../report/fit_figure.rst",
            category="Fits per vehicle",
            subcategory="{vehicle}",
            labels={"vehicle": "{vehicle}", "model": "{model}"},
        ),
        svg="results/vehicles/{vehicle}/fit_{model}.svg",
    wildcard_constraints:
        model="(order[12]|interior_envelope)(_kalman)?",
    params:
        code=code_digest("plots.py"),
    log:
        "logs/fit_figure/{vehicle}/{model}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/fit_figure.py"


rule innovation_figure:
    input:
        series="results/vehicles/{vehicle}/identify/{model}_series.csv",
        fit="results/vehicles/{vehicle}/fit_{model}.yaml",
    output:
        png=report(
            "results/vehicles/{vehicle}/innovations_{model}.png",
            caption="../report/innovation_figure.rst",
            category="Fits per vehicle",
            subcategory="{vehicle}",
            labels={"vehicle": "{vehicle}", "model": "{model}", "figure": "innovations"},
        ),
        svg="results/vehicles/{vehicle}/innovations_{model}.svg",
    wildcard_constraints:
        model="(order[12]|interior_envelope)_kalman",
    params:
        code=code_digest("plots.py", "diagnostics.py"),
    log:
        "logs/innovation_figure/{vehicle}/{model}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/innovation_figure.py"


rule aggregate:
    input:
        fits=[
            f"results/vehicles/{vid}/fit_order2{TABLE_KEY_SUFFIX}.yaml"
            for vid in second_order_vehicles()
        ],
        kvalues=[
            f"results/vehicles/{vid}/kvalue.yaml"
            for vid in second_order_vehicles()
            if vid in kvalue_vehicles()
        ],
    output:
        **{
            f"{name}_csv": report(
                f"results/tables/{name}.csv",
                caption=f"../report/{name}.rst",
                category="Tables",
                labels={"table": name},
            )
            for name in STUDY_TABLES
        },
        **{
            f"{name}_{ext}": f"results/tables/{name}.{ext}"
            for name in STUDY_TABLES
            for ext in ("md", "tex")
        },
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in second_order_vehicles()},
        with_kvalue=[vid for vid in second_order_vehicles() if vid in kvalue_vehicles()],
        class_test=config["study"]["class_test"],
        code=code_digest("aggregate.py", "tableformat.py"),
    log:
        "logs/aggregate.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/aggregate.py"


rule figure3:
    input:
        order1=f"results/vehicles/{figure3_vehicle()}/identify/order1_series.csv",
        order2=f"results/vehicles/{figure3_vehicle()}/identify/order2_series.csv",
    output:
        png=report(
            "results/figures/figure3.png",
            caption="../report/figure3.rst",
            category="Figures",
            labels={"figure": "3"},
        ),
        svg="results/figures/figure3.svg",
    params:
        vehicle=figure3_vehicle(),
        synthetic=bool(figure3_vehicle())
        and STUDY.vehicles[figure3_vehicle()].data.get("synthetic", False),
        code=code_digest("plots.py"),
    log:
        "logs/figures/figure3.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/figure3.py"


rule figure4:
    input:
        series=[f"results/vehicles/{vid}/identify/order2_series.csv" for vid in figure4_vehicles()],
    output:
        png=report(
            "results/figures/figure4.png",
            caption="../report/figure4.rst",
            category="Figures",
            labels={"figure": "4"},
        ),
        svg="results/figures/figure4.svg",
    params:
        vehicles=figure4_vehicles(),
        synthetic=any(
            STUDY.vehicles[vid].data.get("synthetic", False) for vid in figure4_vehicles()
        ),
        code=code_digest("plots.py"),
    log:
        "logs/figures/figure4.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/figure4.py"


rule figure5:
    input:
        table3="results/tables/table3.csv",
    output:
        a_png=report(
            "results/figures/figure5a.png",
            caption="../report/figure5a.rst",
            category="Figures",
            labels={"figure": "5a"},
        ),
        a_svg="results/figures/figure5a.svg",
        b_png=report(
            "results/figures/figure5b.png",
            caption="../report/figure5b.rst",
            category="Figures",
            labels={"figure": "5b"},
        ),
        b_svg="results/figures/figure5b.svg",
    params:
        code=code_digest("plots.py"),
    log:
        "logs/figures/figure5.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/figure5.py"


rule reference:
    input:
        refs=[path for path, _ in REFERENCES],
        fits=[f"results/vehicles/{ref['vehicle']}/fit_{ref['model']}.yaml" for _, ref in REFERENCES],
        windows=[
            f"results/vehicles/{ref['vehicle']}/clean/{window}.csv"
            for _, ref in REFERENCES
            for window in identification_windows(ref["vehicle"])
        ],
    output:
        csv=report(
            "results/tables/reference.csv",
            caption="../report/reference.rst",
            category="Tables",
            labels={"table": "reference"},
        ),
        md="results/tables/reference.md",
    params:
        # per reference, in the order of input.refs: its vehicle's config and clean windows
        vehicles=[STUDY.vehicles[ref["vehicle"]].data for _, ref in REFERENCES],
        windows=[
            {
                window: f"results/vehicles/{ref['vehicle']}/clean/{window}.csv"
                for window in identification_windows(ref["vehicle"])
            }
            for _, ref in REFERENCES
        ],
        code=code_digest("reference.py", "identify.py", "pem.py", "models.py", "metrics.py"),
    log:
        "logs/reference.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/reference.py"
