# The standardized static k value (eq. 10) with its steady-state verdict and u(k).


rule kvalue:
    input:
        window="results/vehicles/{vehicle}/clean/kvalue.csv",
    output:
        "results/vehicles/{vehicle}/kvalue.yaml",
    params:
        vehicle=lambda wildcards: STUDY.vehicles[wildcards.vehicle].data,
        code=code_digest("kvalue.py", "fit.py"),
    log:
        "logs/kvalue/{vehicle}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/kvalue.py"


# The figure is its own job: editing the plotting code redraws it without recomputing k (and
# everything downstream of k).
rule kvalue_figure:
    input:
        window="results/vehicles/{vehicle}/clean/kvalue.csv",
        record="results/vehicles/{vehicle}/clean/record.csv",
        result="results/vehicles/{vehicle}/kvalue.yaml",
    output:
        png=report(
            "results/vehicles/{vehicle}/kvalue.png",
            caption="../report/kvalue_figure.rst",
            category="Static k per vehicle",
            labels={"vehicle": "{vehicle}"},
        ),
        svg="results/vehicles/{vehicle}/kvalue.svg",
    params:
        synthetic=lambda wildcards: STUDY.vehicles[wildcards.vehicle].data.get(
            "synthetic", False
        ),
        code=code_digest("plots.py"),
    log:
        "logs/kvalue_figure/{vehicle}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/kvalue_figure.py"


rule kvalue_table:
    input:
        results=expand("results/vehicles/{vehicle}/kvalue.yaml", vehicle=kvalue_vehicles()),
        truth="results/campaign/ground_truth.csv" if CAMPAIGN else [],
    output:
        "results/tables/kvalue.csv",
    params:
        vehicles=kvalue_vehicles(),
        code=code_digest("aggregate.py"),
    log:
        "logs/kvalue_table.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/kvalue_table.py"
