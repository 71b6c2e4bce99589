# The standardized static k value (eq. 10) with its steady-state verdict and u(k).


rule kvalue:
    input:
        window="results/vehicles/{vehicle}/clean/kvalue.csv",
    output:
        "results/vehicles/{vehicle}/kvalue.yaml",
    params:
        vehicle=vehicle_data,
        code=script_code("kvalue.py"),
    log:
        "logs/kvalue/{vehicle}.log",
    priority: CHAIN_PRIORITY
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
        # the campaign's truth is of its synthetic vehicles, never of a measured one
        synthetic=[v for v in kvalue_vehicles() if STUDY.vehicles[v].data.get("synthetic")],
        code=script_code("kvalue_table.py"),
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
