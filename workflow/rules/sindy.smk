# The optional SINDy cross-check of the grey-box structure (railtherm.sindy; config `sindy:`).


rule sindy:
    input:
        windows=identification_tables,
        fit=second_order_fit,
    output:
        "results/vehicles/{vehicle}/sindy.yaml",
    params:
        vehicle=vehicle_data,
        settings={k: v for k, v in config["sindy"].items() if k != "enabled"},
        code=script_code("sindy.py"),
    log:
        "logs/sindy/{vehicle}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/sindy.py"


rule sindy_summary:
    input:
        results=expand("results/vehicles/{vehicle}/sindy.yaml", vehicle=sindy_vehicles()),
    output:
        csv=report(
            "results/tables/sindy.csv",
            caption="../report/sindy_table.rst",
            category="SINDy cross-check",
        ),
        md="results/tables/sindy.md",
        png=report(
            "results/figures/sindy.png",
            caption="../report/sindy_figure.rst",
            category="SINDy cross-check",
        ),
        svg="results/figures/sindy.svg",
    params:
        vehicles=sindy_vehicles(),
        data={vid: STUDY.vehicles[vid].data for vid in sindy_vehicles()},
        code=script_code("sindy_summary.py"),
    log:
        "logs/sindy/summary.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/sindy_summary.py"
