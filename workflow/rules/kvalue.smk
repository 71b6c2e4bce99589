# The standardized static k value (eq. 10) with its steady-state verdict and u(k).


rule kvalue:
    input:
        window="results/vehicles/{vehicle}/clean/kvalue.csv",
        record="results/vehicles/{vehicle}/clean/record.csv",
    output:
        result="results/vehicles/{vehicle}/kvalue.yaml",
        figure=multiext("results/vehicles/{vehicle}/kvalue", ".png", ".svg"),
    params:
        vehicle=lambda wildcards: STUDY.vehicles[wildcards.vehicle].data,
        code=code_digest("kvalue.py", "plots.py"),
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


rule kvalue_table:
    input:
        results=expand("results/vehicles/{vehicle}/kvalue.yaml", vehicle=kvalue_vehicles()),
        truth="results/campaign/ground_truth.csv" if CAMPAIGN else [],
    output:
        "results/tables/kvalue.csv",
    params:
        vehicles=kvalue_vehicles(),
        code=code_digest("aggregate.py", "synth.py"),
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
