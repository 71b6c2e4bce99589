# The study's outputs (paper section 6): Tables 1-3, the class statistics, Figures 3-5 and the
# figures of each vehicle; captions for `snakemake --report` in workflow/report.


# Every figure of one vehicle in one job: the static k test (railtherm.report.plots.kvalue_figure),
# the fit of each model (fit_figure) and the innovations of each Kalman-filter fit
# (innovation_figure). The figures are their own job: editing the plotting code redraws them
# without recomputing k or a fit. A rule's outputs are fixed, so vehicles with another set of
# figures (no k window, other models) get a rule of their own: `vehicle_figures`,
# `vehicle_figures_2`, ... (StudyPlan.rule_groups, railtherm.study.plan). study.figures: false
# plans none.
for _rule, (_has_k, _keys), _constraint in rule_groups("vehicle_figures", figure_signature):
    _kalman = [key for key in _keys if key.endswith(fitsettings.KALMAN_SUFFIX)]

    rule:
        name: _rule
        input:
            **(
                {
                    "kvalue_window": "results/vehicles/{vehicle}/clean/kvalue.csv",
                    "kvalue_record": "results/vehicles/{vehicle}/clean/record.csv",
                    "kvalue_result": "results/vehicles/{vehicle}/kvalue.yaml",
                }
                if _has_k
                else {}
            ),
            **{
                f"series_{key}": f"results/vehicles/{{vehicle}}/identify/{key}_series.csv"
                for key in _keys
            },
            **{f"fit_{key}": f"results/vehicles/{{vehicle}}/fit_{key}.yaml" for key in _keys},
        output:
            **(
                {
                    "kvalue_png": report(
                        "results/vehicles/{vehicle}/kvalue.png",
                        caption="../report/kvalue_figure.rst",
                        category="Static k per vehicle",
                        labels={"vehicle": "{vehicle}"},
                    ),
                    "kvalue_svg": "results/vehicles/{vehicle}/kvalue.svg",
                }
                if _has_k
                else {}
            ),
            **{
                f"fit_{key}_png": report(
                    f"results/vehicles/{{vehicle}}/fit_{key}.png",
                    caption="../report/fit_figure.rst",
                    category="Fits per vehicle",
                    subcategory="{vehicle}",
                    labels={"vehicle": "{vehicle}", "model": key},
                )
                for key in _keys
            },
            **{f"fit_{key}_svg": f"results/vehicles/{{vehicle}}/fit_{key}.svg" for key in _keys},
            **{
                f"innovations_{key}_png": report(
                    f"results/vehicles/{{vehicle}}/innovations_{key}.png",
                    caption="../report/innovation_figure.rst",
                    category="Fits per vehicle",
                    subcategory="{vehicle}",
                    labels={"vehicle": "{vehicle}", "model": key, "figure": "innovations"},
                )
                for key in _kalman
            },
            **{
                f"innovations_{key}_svg": f"results/vehicles/{{vehicle}}/innovations_{key}.svg"
                for key in _kalman
            },
        wildcard_constraints:
            vehicle=_constraint,
        params:
            kvalue=_has_k,
            models=list(_keys),
            synthetic=vehicle_synthetic,
            code=script_code("vehicle_figures.py"),
        log:
            "logs/vehicle_figures/{vehicle}.log",
        threads: 1
        resources:
            mem_mb=1000,
            runtime=5,
        conda:
            "../envs/railtherm.yaml"
        script:
            "../scripts/vehicle_figures.py"


rule aggregate:
    input:
        fits=[
            f"results/vehicles/{vid}/fit_{table_key(vid, 2)}.yaml"
            for vid in second_order_vehicles()
        ],
        kvalues=[
            f"results/vehicles/{vid}/kvalue.yaml"
            for vid in second_order_vehicles()
            if has_kvalue(vid)
        ],
        # C_bar (eq. 9) beside C_total = C + C_veh in Table 2
        first_order=[
            f"results/vehicles/{vid}/fit_{table_key(vid, 1)}.yaml"
            for vid in second_order_vehicles()
            if has_fit(vid, 1)
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
        with_kvalue=[vid for vid in second_order_vehicles() if has_kvalue(vid)],
        with_first_order=[vid for vid in second_order_vehicles() if has_fit(vid, 1)],
        left_out=PLAN.without_second_order(),
        class_test=config["study"]["class_test"],
        code=script_code("aggregate.py"),
    log:
        "logs/aggregate.log",
    priority: CHAIN_PRIORITY
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
        order1=table_series(figure3_vehicle(), 1),
        order2=table_series(figure3_vehicle(), 2),
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
        code=script_code("figure3.py"),
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
        series=[table_series(vid, 2) for vid in figure4_vehicles()],
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
        code=script_code("figure4.py"),
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
        code=script_code("figure5.py"),
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
            for window in PLAN.identification_windows(ref["vehicle"])
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
                for window in PLAN.identification_windows(ref["vehicle"])
            }
            for _, ref in REFERENCES
        ],
        code=script_code("reference.py"),
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
