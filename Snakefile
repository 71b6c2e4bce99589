# railtherm: regenerate the rail-vehicle thermal study from the configs in config/.
# Thin by design: every number is computed by the railtherm package; rules live in workflow/rules.
from snakemake.exceptions import WorkflowError
from snakemake.utils import min_version, validate

from railtherm.errors import RailthermError
from railtherm.yamlio import read_yaml

min_version("9.0")


# the study config is read by railtherm's own loader first, as `railtherm validate` reads it: a
# key given twice or an alias bomb stops here, before Snakemake's loader takes the last value
# of a key or builds the bomb
try:
    read_yaml("config/config.yaml")
except RailthermError as err:
    raise WorkflowError(f"invalid configuration: {err}") from None


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


validate(config, "railtherm/schemas/study.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/synthesize.smk"
include: "workflow/rules/clean.smk"
include: "workflow/rules/kvalue.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/study.smk"
include: "workflow/rules/audit.smk"
include: "workflow/rules/sindy.smk"
include: "workflow/rules/predict.smk"
include: "workflow/rules/bayes.smk"


rule all:
    input:
        all_outputs(),
    default_target: True
