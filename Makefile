# The two commands of README.md. Both run the set-up first (system packages, once).
.PHONY: setup run test figures docs-figures ac-docs native perf-docs scaling-docs feti-docs integrators-docs variable-horizon-docs coupling-docs

setup:
	@scripts/setup.sh

# The main job, the mission's three questions (make-style: a second `make run` runs only what is
# missing): how accurate and how fast the methods are (the quick study: convergence, scaling,
# run time against error; its records by status, its summary table and its report), where
# the explicit integrators stop being stable (a boundary search, seconds), and which integrator
# reaches an error target at the least run time, with which grid and step (an error-target
# search, seconds). The last lines are those two answers and the three reports.
run: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/quick.json
	target/release/nlstudy status studies/quick.json
	target/release/nlstudy collect studies/quick.json
	target/release/nlstudy report studies/quick.json
	target/release/nlstudy run studies/quick_stability.json
	target/release/nlstudy run studies/quick_target.json
	@echo "reports: results/quick/report.html (accuracy, scaling, run time against error)," \
	  "results/quick_stability/report.html (stability limits)," \
	  "results/quick_target/report.html (the cheapest configuration for an error target)"

# Tests and runs share the release profile and the features of every dependency (see
# workspace-hack/Cargo.toml), so after `make run` the tests compile only the project's crates, and
# the reverse. scripts/run-tests builds the binaries and the tests and runs every test (`cargo
# test --release --workspace -- --include-ignored` does the same, one binary after another): the
# Slurm test in a lane of its own, started while the other tests compile, the others under
# cargo-nextest beside it, and the timing tests alone at the end. It runs the system tests too
# (Slurm, Chromium, Python's vtk, a tmpfs, mpirun), which a bare `cargo test` leaves out, saying
# "system tests: off"; here a missing component fails them.
test:
	@scripts/setup.sh --tests
	scripts/run-tests

# Every study of the set, each run (make-style) then collected and plotted into
# results/<study>/figures/.
STUDIES := quick quick_stability quick_target convergence stability stability_map local_methods threads ranks work_precision patch ac_limit perf feti_weak feti_strong feti_projection integrators variable_horizon coupling error_target error_target_local
figures: setup
	cargo build --release --workspace
	for study in $(STUDIES); do target/release/nlstudy run studies/$$study.json || exit 1; done

# The figures the README shows, regenerated and copied to docs/figures/.
docs-figures: figures
	mkdir -p docs/figures
	cp results/convergence/figures/convergence.svg docs/figures/convergence.svg
	cp results/work_precision/figures/work_precision.svg docs/figures/work_precision.svg
	cp results/ranks/figures/strong.svg docs/figures/ranks_strong.svg

# The integrators study (about 4 minutes; 21 s of it forward Euler at dt = h²/4, three times) and
# the figures docs/integrators.md shows.
integrators-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/integrators.json
	mkdir -p docs/figures/integrators
	cp results/integrators/figures/*.svg docs/figures/integrators/

# docs/variable_horizon.md's figures and tables: [LSSM]'s patch tests (a few seconds), then the
# formulations compared (studies/formulations.json, about 3.5 minutes).
variable-horizon-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/variable_horizon.json
	mkdir -p docs/figures/variable_horizon
	cp results/variable_horizon/figures/*.svg docs/figures/variable_horizon/
	target/release/nlstudy run studies/formulations.json

# docs/coupling.md's figures and tables ([LSSM]'s local–nonlocal coupling and the seamless one),
# a few seconds.
coupling-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/coupling.json
	mkdir -p docs/figures/coupling
	cp results/coupling/figures/*.svg docs/figures/coupling/

# The asymptotic-compatibility page docs/ac_limit.md and its figures, from the patch and ac_limit
# studies (about 45 s for a first run).
ac-docs: setup
	cargo build --release --workspace
	scripts/ac_report.sh

# The binaries built for this machine's processor (AVX-512 here), in their own target directory.
native: setup
	cargo build --release --workspace --target-dir target/native --config 'build.rustflags=["-C", "target-cpu=native"]'

# The perf study (portable build, 2 threads) and its figure in docs/figures/perf/.
perf-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/perf.json
	mkdir -p docs/figures/perf
	cp results/perf/figures/throughput.svg docs/figures/perf/throughput.svg

# The scaling model's runs here (about 40 seconds) and its figure in docs/figures/scaling/.
scaling-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/scaling_model.json
	mkdir -p docs/figures/scaling
	cp results/scaling_model/figures/scaling_model.svg docs/figures/scaling/scaling_model.svg

# The steady solvers' weak and strong scaling studies ([XGDF]; about 11 minutes) and their
# comparison figures in docs/figures/feti/.
feti-docs: setup
	cargo build --release --workspace
	target/release/nlstudy run studies/feti_weak.json
	target/release/nlstudy run studies/feti_strong.json
	target/release/nlstudy run studies/feti_projection.json
	mkdir -p docs/figures/feti
	cp results/feti_weak/figures/comparison.svg docs/figures/feti/weak.svg
	cp results/feti_strong/figures/comparison.svg docs/figures/feti/strong.svg
