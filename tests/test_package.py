"""Package-level promises: the library stands without the workflow engine."""

import subprocess
import sys


def test_library_does_not_import_snakemake():
    modules = ["railtherm", "railtherm.config", "railtherm.synth", "railtherm.cli"]
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in modules)
        + "print('snakemake' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
