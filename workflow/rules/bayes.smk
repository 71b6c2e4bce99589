# Bayesian inference (docs/bayes.md), with `inference: posterior` in the study config: each
# vehicle's Table 1 and Table 2 models sampled by NUTS, a second-order model with the class
# reference model of the study's other vehicles as its prior (partial pooling, empirical
# Bayes), and the study table of maximum likelihood, class prior and posterior side by side.


rule posterior:
    input:
        windows=identification_tables,
        kvalue=kvalue_input,
        k_window=kvalue_window_input,
        fit="results/vehicles/{vehicle}/fit_{model}.yaml",
        table2=lambda w: PLAN.class_prior_input(w.vehicle, w.model),
    output:
        nc="results/vehicles/{vehicle}/fit_{model}.posterior.nc",
        png="results/vehicles/{vehicle}/fit_{model}.posterior.png",
        record="results/vehicles/{vehicle}/posterior_{model}.yaml",
    wildcard_constraints:
        model=r"order[12](_kalman)?",
    params:
        vehicle=vehicle_data,
        vehicles={vid: STUDY.vehicles[vid].data for vid in VEHICLES},
        windows=identification_names,
        settings=config["posterior"],
        min_vehicles=config["reference_model"]["min_vehicles"],
        code=script_code("posterior.py"),
    log:
        "logs/posterior/{vehicle}_{model}.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/posterior.py"


rule pooling:
    input:
        records=[
            f"results/vehicles/{vid}/posterior_{key}.yaml"
            for vid, key in PLAN.posterior_targets()
        ],
    output:
        csv=report(
            "results/tables/pooling.csv",
            caption="../report/pooling.rst",
            category="Tables",
            labels={"table": "pooling"},
        ),
        md="results/tables/pooling.md",
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in VEHICLES},
        code=script_code("pooling.py"),
    log:
        "logs/pooling.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/pooling.py"
