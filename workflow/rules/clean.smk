# Raw CWT files -> tidy, uniformly sampled tables, one per window (railtherm.ingest).


rule clean:
    input:
        window_raw_file,
    output:
        "results/vehicles/{vehicle}/clean/{window}.csv",
    params:
        vehicle=lambda wildcards: STUDY.vehicles[wildcards.vehicle].data,
        raw=raw_digest,
        code=code_digest("ingest.py"),
    log:
        "logs/clean/{vehicle}/{window}.log",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/railtherm.yaml"
    script:
        "../scripts/clean.py"
