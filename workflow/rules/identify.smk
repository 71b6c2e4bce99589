# Identification of the first- and second-order models by simulation-error PEM (eqs. 15-20).


rule identify:
    input:
        windows=identification_tables,
        kvalue=kvalue_input,
    output:
        estimate="results/vehicles/{vehicle}/identify/{model}.yaml",
        series="results/vehicles/{vehicle}/identify/{model}_series.csv",
    wildcard_constraints:
        model="(order[12]|interior_envelope)(_kalman)?",
    params:
        vehicle=vehicle_data,
        windows=identification_names,
        code=script_code("identify.py"),
    log:
        "logs/identify/{vehicle}/{model}.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/identify.py"


rule check:
    input:
        estimate="results/vehicles/{vehicle}/identify/{model}.yaml",
        series="results/vehicles/{vehicle}/identify/{model}_series.csv",
    output:
        "results/vehicles/{vehicle}/fit_{model}.yaml",
    wildcard_constraints:
        model="(order[12]|interior_envelope)(_kalman)?",
    params:
        check=check_settings,
        code=script_code("check.py"),
    log:
        "logs/check/{vehicle}/{model}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/check.py"


rule fit_table:
    input:
        fits=[
            f"results/vehicles/{vid}/fit_order{n}{TABLE_KEY_SUFFIX}.yaml"
            for vid, n in fit_targets()
        ],
        truth="results/campaign/ground_truth.csv" if CAMPAIGN else [],
    output:
        "results/tables/identification.csv",
    params:
        fits=fit_targets(),
        code=script_code("fit_table.py"),
    log:
        "logs/fit_table.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/fit_table.py"


rule compare_models:
    input:
        fits=[f"results/vehicles/{vid}/fit_{key}.yaml" for vid, key in model_targets()],
    output:
        csv=report(
            "results/tables/models.csv",
            caption="../report/models.rst",
            category="Tables",
            labels={"table": "models"},
        ),
        md="results/tables/models.md",
    params:
        data={vid: STUDY.vehicles[vid].data for vid in VEHICLES},
        code=script_code("compare_models.py"),
    log:
        "logs/compare_models.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/compare_models.py"
