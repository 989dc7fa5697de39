# Two commands: `make run` (build every result) and `make test` (the whole test suite).
# Both create .venv from the pinned requirements.txt when it is missing or out of date.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SNAKEMAKE := $(BIN)/snakemake --cores 2 --workflow-profile workflow/profiles/default

.PHONY: run test test-slurm smoke regimes bench clean-results pull dvc.yaml

$(STAMP): requirements.txt pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --disable-pip-version-check -q -r requirements.txt
	$(BIN)/pip install --disable-pip-version-check -q --no-deps -e .
	touch $@

run: $(STAMP)  ## rebuild all results of params.yaml's scenes at its scale
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE)

smoke: $(STAMP)  ## the whole pipeline at the smoke scale (about a minute)
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE) --config scale=smoke

regimes: $(STAMP)  ## Table 1 under each grasp regime (results/volume_regimes; SCALE=smoke for a quick one)
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE) volume_regimes $(if $(SCALE),--config scale=$(SCALE))

test: $(STAMP)  ## the whole test suite (unit + smoke-scale integration through real Snakemake)
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/pytest

test-slurm: $(STAMP)  ## the smoke scale through a single-node SLURM cluster started here (root; apt-installs slurm-wlm, munge)
	PATH=$(CURDIR)/$(BIN):$$PATH TACTILEPIPE_SLURM_TEST=1 $(BIN)/pytest -m slurm -v tests/test_cluster.py

bench: $(STAMP)  ## benchmarks, each printing ours next to the reference loop and the target
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_volume.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_tool.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_dvc.py

pull: $(STAMP)  ## fetch shared results (dvc pull) and, once DVC finds them current by content, mark them so for Snakemake
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/dvc pull
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python workflow/scripts/mark_pulled.py

dvc.yaml: $(STAMP)  ## regenerate dvc.yaml from the Snakemake graph (run after editing rules, stages or imports)
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python workflow/scripts/dvc_yaml.py

clean-results:  ## remove generated results (raw recordings stay)
	rm -rf results/volume results/volume_regimes results/drift results/logs
