# Two commands: `make run` (build every result) and `make test` (the whole test suite).
# Both create .venv from the pinned requirements.txt when it is missing or out of date.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SNAKEMAKE := $(BIN)/snakemake --cores 2 --workflow-profile workflow/profiles/default

.PHONY: run test test-all test-unit test-slurm smoke regimes bench clean-results pull dvc.yaml schema study000-import study000 study000-published

$(STAMP): requirements.txt pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --disable-pip-version-check -q -r requirements.txt
	$(BIN)/pip install --disable-pip-version-check -q --no-deps -e .
	$(BIN)/python workflow/scripts/offline_plots.py
	touch $@

run: $(STAMP)  ## rebuild all results of params.yaml's scenes at its scale
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE)

smoke: $(STAMP)  ## the whole pipeline at the smoke scale (a few minutes; benchmarks/record.md)
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE) --config scale=smoke

regimes: $(STAMP)  ## Table 1 under each grasp regime (results/<build>/volume_regimes; SCALE=smoke for a quick one)
	PATH=$(CURDIR)/$(BIN):$$PATH $(SNAKEMAKE) volume_regimes $(if $(SCALE),--config scale=$(SCALE))

# Study 000 on its own data (docs/reproduce_study_000.md): opt-in, in studies/000/, needs the network once
study000-import: $(STAMP)  ## dvc import-url of study 000's archives and weights (params.yaml public_data.files)
	mkdir -p studies/000/raw/downloads && cd studies/000 && $(CURDIR)/$(BIN)/python -c 'import yaml; [print(n, f["url"]) for n, f in yaml.safe_load(open("params.yaml"))["public_data"]["files"].items()]' | \
	while read name url; do out=raw/downloads/$$name.$${url##*.}; test -f $$out.dvc || \
	PATH=$(CURDIR)/$(BIN):$$PATH dvc import-url "$$url" $$out || exit 1; done

study000: $(STAMP)  ## unpack, ingest, train the full model under both protocols, table beside the paper (GPU: paper scale)
	cd studies/000 && PATH=$(CURDIR)/$(BIN):$$PATH dvc repro protocols

study000-published: $(STAMP)  ## the published weights over every frame (contaminated: a check of preprocessing)
	cd studies/000 && PATH=$(CURDIR)/$(BIN):$$PATH dvc repro published

test: $(STAMP)  ## the test suite CI runs (unit + smoke-scale integration through real Snakemake), on 2 workers
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/pytest -n 2 -m "not extended"

test-all: $(STAMP)  ## every test: also the `extended` ones and both emulated CPUs (about an hour on 2 cores)
	PATH=$(CURDIR)/$(BIN):$$PATH TACTILEPIPE_QEMU_CPUS=all $(BIN)/pytest -n 2

test-unit: $(STAMP)  ## the quick loop: unit tests not marked slow (no model trained beyond a few steps), on 2 workers
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/pytest -n 2 -m "not slow" tests/unit

test-slurm: $(STAMP)  ## the smoke scale through a single-node SLURM cluster started here (root; apt-installs slurm-wlm, munge)
	PATH=$(CURDIR)/$(BIN):$$PATH TACTILEPIPE_SLURM_TEST=1 $(BIN)/pytest -m slurm -v tests/integration/test_cluster.py

bench: $(STAMP)  ## benchmarks, each printing ours next to the reference loop and the target
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_volume.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_tool.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_dvc.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_train_jobs.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_kernels.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_live.py
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python benchmarks/bench_scheduler.py

pull: $(STAMP)  ## fetch shared results (dvc pull) and, once DVC finds them current by content, mark them so for Snakemake
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python workflow/scripts/mark_pulled.py --pull

dvc.yaml: $(STAMP)  ## regenerate dvc.yaml from the Snakemake graph, and studies/000/dvc.yaml (run after editing rules, stages or imports)
	PATH=$(CURDIR)/$(BIN):$$PATH $(BIN)/python workflow/scripts/dvc_yaml.py

schema: $(STAMP)  ## regenerate params.yaml's JSON schema from the parameter models (run after editing src/tactilepipe/core/parameters/)
	$(BIN)/python workflow/scripts/params_schema.py

clean-results:  ## remove the results of every build, or of one (BUILD=smoke); raw recordings and results/portability.json stay
	rm -rf $(if $(BUILD),results/$(BUILD),$(wildcard results/*/))
