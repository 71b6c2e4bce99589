# The optional SINDy cross-check of the grey-box structure (railtherm.study.sindy; config
# `sindy:`).


# The SINDy fits of up to sindy.vehicles_per_job vehicles share one job: pysindy's import
# (scikit-learn) costs more than a vehicle's fit. The batches follow the study's vehicle order;
# the first batch's rule is `sindy`, further ones `sindy_2`, `sindy_3`, ...
for _rule, _batch in sindy_batches():

    rule:
        name: _rule
        input:
            **{
                f"windows_{vid}": list(PLAN.identification_tables(vid))
                for vid in _batch
            },
            **{
                f"fit_{vid}": f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
                for vid in _batch
                if has_fit(vid, 2)
            },
        output:
            **{f"sindy_{vid}": f"results/vehicles/{vid}/sindy.yaml" for vid in _batch},
        params:
            # what a SINDy fit reads of a vehicle's config: an edit of anything else reruns none
            vehicles={
                vid: {"id": vid, "synthetic": STUDY.vehicles[vid].data.get("synthetic", False)}
                for vid in _batch
            },
            settings=SINDY_SETTINGS,
            code=script_code("sindy.py"),
        log:
            f"logs/sindy/{_rule}.log",
        threads: 1
        resources:
            mem_mb=1000,
            runtime=5 * len(_batch),
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
