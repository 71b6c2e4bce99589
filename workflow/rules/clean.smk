# Raw CWT files -> tidy, uniformly sampled tables (railtherm.data.ingest): one job per vehicle
# writes every table of that vehicle (its windows, the k window and the whole record), each raw file
# read once. A rule's outputs are fixed, so vehicles whose tables have other names get a rule of
# their own: `clean` for the first set of names, `clean_2`, ... (StudyPlan.rule_groups,
# railtherm.study.plan).

for _rule, _tables, _constraint in rule_groups("clean", tidy_tables):

    rule:
        name: _rule
        input:
            clean_input,
        output:
            expand("results/vehicles/{{vehicle}}/clean/{table}.csv", table=_tables),
        wildcard_constraints:
            vehicle=_constraint,
        params:
            vehicle=vehicle_data,
            tables=list(_tables),
            sources=clean_sources,
            raw=raw_digests,
            code=script_code("clean.py"),
        log:
            "logs/clean/{vehicle}.log",
        priority: CHAIN_PRIORITY
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        conda:
            "../envs/railtherm.yaml"
        script:
            "../scripts/clean.py"
