# Two commands on a fresh machine: `make grade` and `make test`.
# Each creates .venv when it is missing and installs robolab into it.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

export MPLBACKEND := Agg

.PHONY: help venv test test-suite test-grading test-grading-running test-grading-other test-rest test-notebooks grade lab bench data lint notebooks clean

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

# The test suite (in three parts: the grader's running and loading tests, which hold the
# load test and the fidelity suite; the rest of the grader's tests; everything else) and
# the solved notebooks run as four jobs on the two cores (make -j 2), longest first, so
# that both cores stay busy to the end; each one's output is printed when it is done
# (--output-sync), and any failing fails `make test`. Together the three pytest runs
# collect every test once. `make test-suite` runs the whole suite in one pytest.
GRADING_RUNNING := tests/grading/running tests/grading/loading

test: $(STAMP)
	@$(MAKE) --no-print-directory -j 2 --output-sync=target test-grading-running test-rest test-grading-other test-notebooks

test-suite: $(STAMP)
	$(BIN)/python -m pytest

test-grading: $(STAMP)
	$(BIN)/python -m pytest tests/grading

test-grading-running: $(STAMP)
	$(BIN)/python -m pytest $(GRADING_RUNNING)

test-grading-other: $(STAMP)
	$(BIN)/python -m pytest tests/grading $(addprefix --ignore=,$(GRADING_RUNNING))

test-rest: $(STAMP)
	$(BIN)/python -m pytest --ignore=tests/grading

test-notebooks: $(STAMP)
	$(BIN)/robolab solve notebooks/ -o build/solved
	$(BIN)/python tools/add_figure_audit.py build/solved
	$(BIN)/robolab release build/student
	rm -rf $(STUDENT_VENV) && $(PYTHON) -m venv $(STUDENT_VENV)
	$(STUDENT_VENV)/bin/python -m pip install --quiet --disable-pip-version-check --no-compile build/student/dist/robolab-*.whl pytest nbval
	cd build/solved && ../student-venv/bin/python -m pytest --nbval-lax --nbval-current-env --nbval-cell-timeout=120 -p no:cacheprovider . -o testpaths=. -o addopts=""

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
