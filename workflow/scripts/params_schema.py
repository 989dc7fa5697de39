"""Write params.yaml's JSON schema from the parameter models: `make schema` (or `python workflow/scripts/params_schema.py`).

The models in src/tactilepipe/core/parameters/ are the one place a parameter's type, range and
description are written; the schema `tactilepipe.core.config` validates with is generated from
them and shipped as package data (workflow/schemas/params.schema.json links to it).

`--check` exits 1 and prints a diff when the committed schema is not what the models give.
"""

from __future__ import annotations

import argparse
import difflib
import sys
from pathlib import Path

from tactilepipe.core.atomic import write_text
from tactilepipe.core.config import PARAMS_SCHEMA
from tactilepipe.core.parameters.schema import params_schema_text


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 with a diff if the schema is not generated")
    parser.add_argument("--out", type=Path, default=Path(str(PARAMS_SCHEMA)))
    args = parser.parse_args(argv)
    text = params_schema_text()
    current = args.out.read_text() if args.out.exists() else ""
    if text == current:
        return 0
    if args.check:
        sys.stdout.writelines(difflib.unified_diff(current.splitlines(True), text.splitlines(True),
                                                   f"{args.out} (committed)", f"{args.out} (generated)"))
        print(f"\n{args.out} is not what the parameter models give: run `make schema` and commit it.")
        return 1
    write_text(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
