# The two commands of the README: `make demo` (the main job: train the default reach
# policy, evaluate it, write the plot) and `make test`.
# Each creates .venv on first use and installs what it needs into it.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip --disable-pip-version-check -q

.PHONY: demo test serve-demo bench clean

# torch==2.13.0 first: that CPU wheel is on these machines; any other torch pulls
# gigabytes of CUDA packages (stable-baselines3 in the test and train extras needs it).
# setup.py and the C kernels too: a changed kernel is rebuilt by the editable install.
$(VENV)/.installed: pyproject.toml setup.py $(wildcard franka_sim_gym/*/_*.c franka_sim_gym/*/*/_*.c franka_sim_gym/*/_*.h)
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install torch==2.13.0
	$(PIP) install -e '.[test]'
	touch $@

$(VENV)/.train: $(VENV)/.installed
	$(PIP) install -e '.[train]'
	touch $@

demo: $(VENV)/.train
	$(PY) examples/train_sb3.py --out runs/reach
	$(PY) examples/evaluate.py --model runs/reach/model.zip --episodes 100
	$(PY) examples/record_video.py --model runs/reach/model.zip --out runs/reach/policy.gif

# The socket server and a pylibfranka client moving the arm.
serve-demo: $(VENV)/.installed
	$(PY) examples/demo.py

# -n auto: one pytest-xdist worker per core; the suite holds its ten minutes on two cores.
test: $(VENV)/.installed
	$(PY) -m ruff check franka_sim_gym tests examples benchmarks
	$(PY) -m pytest -q -n auto

bench: $(VENV)/.installed
	$(PY) benchmarks/cycle_rate.py

clean:
	rm -rf $(VENV) .pytest_cache runs
