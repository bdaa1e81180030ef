# The two commands of README.md. Both run the set-up first (system packages, once).
.PHONY: setup run test

setup:
	@scripts/setup.sh

# The main job. Until the orchestrator lands, it runs the demonstration case and keeps its record.
run: setup
	cargo build --release --workspace
	mkdir -p results/demo
	target/release/nlsolve run --case cases/demo.json > results/demo/record.json.tmp
	mv results/demo/record.json.tmp results/demo/record.json
	@echo "record written to results/demo/record.json"

# Tests and runs share the release profile, so dependencies compile once.
test: setup
	cargo test --release --workspace
