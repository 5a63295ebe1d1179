# projection_server: every target first brings the environment up to date (idempotent).
#   make run                         start the node
#   make test                        run the whole test suite
#   make query Q='member(X, [a])'    send a query to a running node
#   make bench                       run the benchmarks in bench/
#   make reproduce                   the paper's three experiments, tables and report/
#   make docs                        the documentation site, into docs/_build/html
.PHONY: setup run test query bench reproduce docs
SHELL := /bin/bash

setup:
	@tools/bootstrap.sh

run: setup
	@tools/with_env.sh projection_server --ros-args \
	  --params-file install/share/projection_server/config/projection_server.yaml $(ARGS)

test: setup
	@tools/with_env.sh tools/run_tests.sh $(ARGS)

query: setup
	@tools/with_env.sh prolog_query "$$Q" $(ARGS)

bench: setup
	@tools/with_env.sh python bench/query_latency.py
	@tools/with_env.sh python bench/pipeline_overhead.py
	@tools/with_env.sh python bench/projection_throughput.py
	@tools/with_env.sh python bench/flat_memory.py --solutions 200
	@tools/with_env.sh python bench/search_cost.py
	@tools/with_env.sh python bench/robust_answer.py
	@tools/with_env.sh python bench/robust_choice.py
	@tools/with_env.sh python bench/robot_world.py
	@tools/with_env.sh python bench/engines.py

reproduce: setup
	@tools/with_env.sh projection_reproduce --out reports $(ARGS)

docs: setup
	@tools/with_env.sh sphinx-build -W --keep-going -q -b html docs docs/_build/html $(ARGS)
	@echo "docs/_build/html/index.html"
