# Two commands on a fresh machine: `make grade` and `make test`.
# Each creates .venv when it is missing and installs robolab into it.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

export MPLBACKEND := Agg

.PHONY: help venv test test-suite test-grading test-grading-running test-grading-loading test-grading-exports test-grading-other test-mutants test-rest test-notebooks grade lab bench data lint notebooks clean

help:
	@echo "make grade   set up, then grade the example submissions (gradebook in grades/)"
	@echo "make test    set up, then run every test (library, grader, hidden lab tests, notebooks)"
	@echo "make lab     JupyterLab on notebooks/"
	@echo "make bench   run the benchmarks and print their tables"
	@echo "make data    regenerate data/ with the simulator"
	@echo "make lint    ruff"
	@echo "make notebooks  rebuild notebooks/*.ipynb from their text sources notebooks/*.py"

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	@touch $(STAMP)

venv: $(STAMP)

# The solved notebooks run in a fresh venv that has only the student edition's wheel
# (plus pytest and nbval), from their own folder: the labs work without the repository.
# --no-compile: pip would byte-compile every module of numpy, scipy, matplotlib, numba,
# jupyter...; the notebooks import a fraction of them, compiled when first imported
# (byte-compiling is half the install's CPU time: 37 s of 75 s, measured at load 15).
STUDENT_VENV := build/student-venv

# The test suite (in six parts) and the solved notebooks run as seven jobs at once on the
# two cores (make -j 7), each in a session of its own (tools/own_session.py: Linux shares
# the CPU per session, and the grader's workers each have one; in make's session the
# tests run in-process shared one session's share against them all). Run together, the
# jobs that wait (the Gradescope set-up's pip, the time limits, the notebooks' kernels one
# at a time) leave their core to the others instead of idling it, and none waits for a
# slot. Each one's output is printed when it is done (--output-sync), and any failing
# fails `make test`. Together the six pytest runs collect every test once. `make
# test-suite` runs the whole suite in one pytest.
SESSION         := $(CURDIR)/$(BIN)/python $(CURDIR)/tools/own_session.py
GRADING_RUNNING := tests/grading/running
GRADING_LOADING := tests/grading/loading
GRADING_EXPORTS := tests/grading/exports tests/grading/test_instructor_doc.py \
                   tests/grading/test_commands.py tests/grading/test_cli.py
MUTANTS         := tests/labs/mutants
TEST_JOBS       := test-grading-running test-grading-loading test-grading-exports \
                   test-grading-other test-mutants test-rest test-notebooks

test: $(STAMP)
	@$(MAKE) --no-print-directory -j 7 --output-sync=target $(TEST_JOBS)

test-suite: $(STAMP)
	$(BIN)/python -m pytest

test-grading: $(STAMP)
	$(BIN)/python -m pytest tests/grading

test-grading-running: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest $(GRADING_RUNNING)

test-grading-loading: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest $(GRADING_LOADING)

test-grading-exports: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest $(GRADING_EXPORTS)

test-grading-other: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest tests/grading \
	    $(addprefix --ignore=,$(GRADING_RUNNING) $(GRADING_LOADING) $(GRADING_EXPORTS))

test-mutants: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest $(MUTANTS)

test-rest: $(STAMP)
	$(SESSION) $(BIN)/python -m pytest --ignore=tests/grading --ignore=$(MUTANTS)

test-notebooks: $(STAMP)
	$(SESSION) $(BIN)/robolab solve notebooks/ -o build/solved
	$(BIN)/python tools/add_figure_audit.py build/solved
	$(SESSION) $(BIN)/robolab release build/student
	rm -rf $(STUDENT_VENV) && $(PYTHON) -m venv $(STUDENT_VENV)
	$(SESSION) $(STUDENT_VENV)/bin/python -m pip install --quiet --disable-pip-version-check --no-compile build/student/dist/robolab-*.whl pytest nbval
	cd build/solved && $(SESSION) ../student-venv/bin/python -m pytest --nbval-lax --nbval-current-env --nbval-cell-timeout=120 -p no:cacheprovider . -o testpaths=. -o addopts=""

grade: $(STAMP)
	$(BIN)/robolab grade examples/submissions/*/*.ipynb --out grades/ -j 2

lab: $(STAMP)
	$(BIN)/jupyter lab notebooks/

bench: $(STAMP)
	@for b in benchmarks/*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

data: $(STAMP)
	$(BIN)/robolab data --out data/

lint: $(STAMP)
	$(BIN)/ruff check robolab solutions tests benchmarks

notebooks: $(STAMP)
	$(BIN)/python tools/sync_notebooks.py

clean:
	rm -rf $(VENV) build grades .pytest_cache
