# Two commands a newcomer needs:
#   make run    set up what is missing, then train the agent with the synthetic trainer
#   make test   set up what is missing, then run every test
# Both create or reuse the environment in .venv/ at the repository root.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
PACKAGES := attention_common attention_tasks env_node feedback_node saliency_node tamer_node trainer_console session_bag graph_viewer attention_bringup
STAMP := $(VENV)/.installed
# DDS stays on loopback for everything started from here (see README, "Network").
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

.PHONY: setup run test bench lint colcon-check clean

setup: $(STAMP)

$(STAMP): requirements.txt $(foreach p,$(PACKAGES),src/$(p)/setup.py src/$(p)/package.xml)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet -r requirements.txt
	$(BIN)/pip install --quiet --no-deps --no-build-isolation $(foreach p,$(PACKAGES),-e src/$(p))
	touch $@

run: setup
	$(BIN)/attention_train $(ARGS)

# Three pytest workers on 2 cores (topic tests mostly wait) (pytest-xdist),
# each test file whole on one of them, each worker in a ROS
# domain of its own (tests/conftest.py); TEST_WORKERS=0 runs them in this one process.
TEST_WORKERS ?= 3
test: setup
	$(BIN)/python -m pytest tests -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS)

bench: setup
	$(BIN)/python tests/benchmarks/run_all.py

lint: setup
	$(BIN)/ament_flake8 src tests
	$(BIN)/ament_pep257 src tests

clean:
	rm -rf $(VENV) build install log
