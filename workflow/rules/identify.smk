# Identification of the first- and second-order models by simulation-error PEM (eqs. 15-20).


# One identify job and one check job per vehicle, each over all of the vehicle's models: a
# job's time is mostly its interpreter and imports, so a vehicle's fits share them. A rule's
# outputs are fixed, so vehicles with another set of models get rules of their own
# (`identify_2`, `check_2`, ...; StudyPlan.rule_groups, railtherm.study.plan).
for _rule, _keys, _constraint in rule_groups("identify", model_keys):

    rule:
        name: _rule
        input:
            windows=identification_tables,
            kvalue=kvalue_input,
            k_window=kvalue_window_input,
        output:
            **identify_files(_keys),
        wildcard_constraints:
            vehicle=_constraint,
        params:
            vehicle=vehicle_data,
            windows=identification_names,
            models=list(_keys),
            code=script_code("identify.py"),
        log:
            "logs/identify/{vehicle}.log",
        priority: CHAIN_PRIORITY
        threads: 1
        resources:
            mem_mb=2000,
            runtime=10 * len(_keys),
        conda:
            "../envs/railtherm.yaml"
        script:
            "../scripts/identify.py"


for _rule, _keys, _constraint in rule_groups("check", model_keys):

    rule:
        name: _rule
        input:
            **identify_files(_keys),
        output:
            **{f"fit_{key}": f"results/vehicles/{{vehicle}}/fit_{key}.yaml" for key in _keys},
        wildcard_constraints:
            vehicle=_constraint,
        params:
            check=check_settings,
            models=list(_keys),
            code=script_code("check.py"),
        log:
            "logs/check/{vehicle}.log",
        priority: CHAIN_PRIORITY
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
            f"results/vehicles/{vid}/fit_{table_key(vid, n)}.yaml"
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
    priority: CHAIN_PRIORITY
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
