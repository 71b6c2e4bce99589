# The audit of published reference values (railtherm.report.audit): consistency, plausibility,
# fitness as a reference, units, and reproduction by this study's re-estimates.


rule audit:
    input:
        published=config["audit"]["published"] or [],
        ranges=config["audit"]["ranges"],
        estimates=(
            ["results/tables/table2.csv", "results/tables/table3.csv"]
            if second_order_vehicles()
            else []
        ),
    output:
        findings=report(
            "results/audit/findings.csv",
            caption="../report/audit.rst",
            category="Audit of published values",
        ),
        markdown=report(
            "results/audit/audit.md",
            caption="../report/audit.rst",
            category="Audit of published values",
        ),
    params:
        code=script_code("audit.py"),
    log:
        "logs/audit.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/audit.py"
