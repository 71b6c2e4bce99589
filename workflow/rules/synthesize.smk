# The virtual climatic wind tunnel: synthetic raw files from the campaign's declared truth.


rule synthesize:
    output:
        f"{CAMPAIGN_ROOT}/{{vehicle}}/{{filename}}",
    wildcard_constraints:
        vehicle=campaign_file_regex("vehicle"),
        filename=campaign_file_regex("filename"),
    params:
        spec=lambda wildcards: synth.vehicle_spec(CAMPAIGN, wildcards.vehicle),
        code=script_code("synthesize.py"),
    log:
        "logs/synthesize/{vehicle}/{filename}.log",
    priority: CHAIN_PRIORITY
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/synthesize.py"


rule ground_truth:
    input:
        config["campaign"] if CAMPAIGN else [],
    output:
        truth="results/campaign/ground_truth.csv",
        sources="results/campaign/ground_truth_sources.csv",
    params:
        code=script_code("ground_truth.py"),
    log:
        "logs/ground_truth.log",
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/ground_truth.py"
