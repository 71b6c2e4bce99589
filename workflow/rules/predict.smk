# Predictions from the identified models: the study's scenarios through every vehicle's
# second-order model, and the leave-one-out validation of the class reference model.


rule simulate:
    input:
        fits=[
            f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
            for vid in second_order_vehicles()
        ],
        # with inference: posterior, the bands come from the posteriors
        posteriors=PLAN.posteriors_of(
            [
                f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
                for vid in second_order_vehicles()
            ]
        ),
        scenarios=scenario_files(),
    output:
        csv=report(
            "results/tables/scenarios.csv",
            caption="../report/scenarios.rst",
            category="Tables",
            labels={"table": "scenarios"},
        ),
        md="results/tables/scenarios.md",
        png=report(
            "results/figures/scenarios.png",
            caption="../report/scenarios_figure.rst",
            category="Figures",
            labels={"figure": "scenarios"},
        ),
        svg="results/figures/scenarios.svg",
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in second_order_vehicles()},
        scenarios=config["scenarios"]["files"],
        figure=getattr(figure_scenario(), "name", None),
        draws=config["scenarios"]["draws"],
        seed=config["scenarios"]["seed"],
        code=script_code("simulate.py"),
    log:
        "logs/simulate.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/simulate.py"


rule reference_validation:
    input:
        table2="results/tables/table2.csv",
        fits=[
            f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
            for vid in second_order_vehicles()
        ],
        series=[
            table_series(vid, 2)
            for vid in second_order_vehicles()
        ],
        scenario=getattr(figure_scenario(), "file", []),
        profiles=scenario_files(),
        truth="results/campaign/ground_truth.csv" if CAMPAIGN else [],
    output:
        csv=report(
            "results/tables/reference_validation.csv",
            caption="../report/reference_validation.rst",
            category="Tables",
            labels={"table": "reference_validation"},
        ),
        md="results/tables/reference_validation.md",
        png=report(
            "results/figures/reference_validation.png",
            caption="../report/reference_validation_figure.rst",
            category="Figures",
            labels={"figure": "reference_validation"},
        ),
        svg="results/figures/reference_validation.svg",
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in second_order_vehicles()},
        min_vehicles=config["reference_model"]["min_vehicles"],
        draws=config["scenarios"]["draws"],
        seed=config["scenarios"]["seed"],
        code=script_code("reference_validation.py"),
    log:
        "logs/reference_validation.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/reference_validation.py"


rule design:
    input:
        table2="results/tables/table2.csv",
        fits=[
            f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
            for vid in second_order_vehicles()
        ],
        series=[table_series(vid, 2) for vid in second_order_vehicles()],
        kvalues=[
            f"results/vehicles/{vid}/kvalue.yaml"
            for vid in second_order_vehicles()
            if has_kvalue(vid)
        ],
    output:
        csv=report(
            "results/tables/design.csv",
            caption="../report/design.rst",
            category="Tables",
            labels={"table": "design"},
        ),
        md="results/tables/design.md",
        png=report(
            "results/figures/design.png",
            caption="../report/design_figure.rst",
            category="Figures",
            labels={"figure": "design"},
        ),
        svg="results/figures/design.svg",
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in second_order_vehicles()},
        with_kvalue=[vid for vid in second_order_vehicles() if has_kvalue(vid)],
        target=config["design"]["target"],
        draws=config["design"]["draws"],
        seed=config["design"]["seed"],
        code=script_code("design.py"),
    log:
        "logs/design.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/design.py"


rule weather_year:
    input:
        lambda wc: weather_file(wc.year),
    output:
        "results/weather/{year}.year.pickle",
    params:
        code=script_code("weather_year.py"),
    log:
        "logs/weather_year/{year}.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/weather_year.py"


rule energy:
    input:
        fits=lambda wc: [
            f"results/vehicles/{wc.vehicle}/fit_{table_key(wc.vehicle, n)}.yaml"
            for vid, n in PLAN.energy_fits()
            if vid == wc.vehicle
        ],
        # with inference: posterior, the draws come from the posteriors
        posteriors=lambda wc: PLAN.posteriors_of(
            [
                f"results/vehicles/{wc.vehicle}/fit_{table_key(wc.vehicle, n)}.yaml"
                for vid, n in PLAN.energy_fits()
                if vid == wc.vehicle
            ]
        ),
        weather=[f"results/weather/{year}.year.pickle" for year in weather_years(config)],
        profile=lambda wc: energy_profile(config, STUDY.vehicles[wc.vehicle].data.get("class", "")),
    output:
        "results/energy/{vehicle}.csv",
    params:
        vehicle=lambda wc: STUDY.vehicles[wc.vehicle].data,
        index=lambda wc: list(STUDY.vehicles).index(wc.vehicle),
        what_if=config["energy"]["what_if"],
        step_s=config["energy"]["step_s"],
        draws=config["energy"]["draws"],
        seed=config["energy"]["seed"],
        hold=config["energy"]["hold"],
        code=script_code("energy.py"),
    log:
        "logs/energy/{vehicle}.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/energy.py"


rule energy_table:
    input:
        tables=[f"results/energy/{vid}.csv" for vid in PLAN.energy_vehicles()],
        fits=[
            f"results/vehicles/{vid}/fit_{table_key(vid, n)}.yaml"
            for vid, n in PLAN.energy_fits()
        ],
        profiles=energy_profiles(config),
    output:
        csv=report(
            "results/tables/annual_energy.csv",
            caption="../report/annual_energy.rst",
            category="Tables",
            labels={"table": "annual_energy"},
        ),
        md="results/tables/annual_energy.md",
        png=report(
            "results/figures/annual_energy.png",
            caption="../report/annual_energy_figure.rst",
            category="Figures",
            labels={"figure": "annual_energy"},
        ),
        svg="results/figures/annual_energy.svg",
    params:
        vehicles={vid: STUDY.vehicles[vid].data for vid in PLAN.energy_vehicles()},
        fit_vehicles=[vid for vid, _ in PLAN.energy_fits()],
        step_s=config["energy"]["step_s"],
        code=script_code("energy_table.py"),
    log:
        "logs/energy_table.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/energy_table.py"
