# The README's two commands: `make run` (the main job on its defaults) and `make test`.
# Both set up everything on a fresh Debian machine: Mesa for off-screen rendering, a virtualenv,
# the CPU build of torch and this package.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# NO_MKDOCS_2_WARNING: the Material theme's notice about MkDocs 2, printed on every build
MKDOCS := NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs
MESA_PACKAGES := libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libosmesa6
export MUJOCO_GL ?= egl

.PHONY: run main-budget external-screening expert-video task-pictures test docs bench study study-extension study-rfcl study-rfcl-extension study-external study-external-extension report compress-results setup gl browser clean

# The main job: what the package is for, AuxSS against SAC from p0 on the same 5 seeds (80,000 steps, as
# one sweep of two 5-seed jobs, one per core; 17 min on the idle 2-core machine, set-up included), then the report
# (figures, per-seed reach counts, the pairwise tests), its two comparison tables printed, and a
# rollout video of AuxSS's seed 0. Safe to run again: the sweep skips finished runs and resumes others.
MAIN_STEPS ?= 80000
MAIN_OUT ?= runs/main
run: setup
	$(BIN)/lava-bridge-bench sweep --methods auxss,sac --seeds 0-4 --steps $(MAIN_STEPS) --eval-every $$(( $(MAIN_STEPS) / 8 )) \
	    --workers 2 --out $(MAIN_OUT)
	$(BIN)/lava-bridge-bench report $(MAIN_OUT) --out $(MAIN_OUT)/report
	$(BIN)/lava-bridge-bench video $(MAIN_OUT)/auxss-d500/seed0 --episodes 1
	@awk '/^## (Seeds reaching|Pairwise tests)/ {show = 1} /^## / && !/^## (Seeds reaching|Pairwise tests)/ {show = 0} show' \
	    $(MAIN_OUT)/report/report.md
	@echo "report: $(MAIN_OUT)/report/report.md (figures beside it); video: $(MAIN_OUT)/auxss-d500/seed0/rollouts.mp4"

# The main job's budget: its two groups evaluated every 5,000 steps up to its 80,000, so that docs/index.md
# ("Why 80,000 steps", generated from results/main_budget) shows at which
# budget AuxSS's seeds reach p0 success 0.8 and SAC's do not. Resumable like every sweep.
main-budget: setup
	$(BIN)/lava-bridge-bench sweep --methods auxss,sac --seeds 0-4 --steps 80000 --eval-every 5000 --workers 2 \
	    --out runs/main_budget
	$(BIN)/lava-bridge-bench export runs/main_budget results/main_budget
	$(BIN)/python -m lava_bridge_mj.eval.analysis.doc_tables

# The external tasks' screening on the tuning seeds 100-104 (docs/external-tasks.md, "Screening"): SAC from
# p0 and AuxSS on both mazes to 300,000 steps, evaluated every 25,000; its rule picks each maze's study
# budget (eval/analysis/doc_tables.py, screening_budget).
external-screening: setup
	$(BIN)/lava-bridge-bench sweep --methods sac,auxss --envs PointMaze_Medium-v3,PointMaze_Large-v3 --seeds 100-104 \
	    --steps 300000 --eval-every 25000 --seeds-per-job 5 --workers 2 --out runs/external_screening
	$(BIN)/lava-bridge-bench export runs/external_screening results/external_screening
	$(BIN)/python -m lava_bridge_mj.eval.analysis.doc_tables

expert-video: setup
	$(BIN)/python -m lava_bridge_mj.eval.video --expert --out runs/expert.mp4

# docs/tasks.png: every task of the suite from its top camera, with the expert's paths
task-pictures: setup
	$(BIN)/python -m lava_bridge_mj.pictures --out docs/tasks.png

# The documentation site built with --strict first (a broken link, anchor or API reference fails it),
# then two pytest workers (pytest-xdist), one per core; --dist loadfile keeps each test file in one
# worker, so the runs a file's fixtures train once are shared by its tests, as in a serial run. Every
# result is appended to TEST_LOG as its test finishes (pytest-reportlog), and on failure the failed tests
# are printed from it: they are named even when pytest's controller dies before its own summary. The
# exit status is pytest's.
TEST_LOG := .pytest-results.jsonl
test: setup browser
	$(MKDOCS) build --strict
	$(BIN)/python -m pytest -n 2 --dist loadfile --report-log=$(TEST_LOG) || { status=$$?; $(BIN)/python tests/failures.py $(TEST_LOG); exit $$status; }

# The documentation site (mkdocs.yml) into site/: open site/index.html, or `$(MKDOCS) serve` to browse it live.
docs: setup
	$(MKDOCS) build --strict

bench: setup
	$(BIN)/python bench/env_throughput.py

# The start-distribution study: SAC, the five demo start distributions and HySAC+AuxSS on every task of
# lava_bridge_mj.SUITE, evaluation seeds 0-19 (the tuning seeds, 100 and up, never), as one-thread jobs of
# 10 seeds, two at a time; the two crossings at the paper's 300,000 steps, where 100,000 solve nothing.
# The start distributions, which the study's questions compare, train first, task by task: the tasks whose
# screening spread them at 100,000 steps (the decoy, the far start), then the two crossings, then the narrow
# bridge and LavaBridge-v0; the baselines (SAC, HySAC+AuxSS) last. About 32 hours on the 2-core machine at
# its measured 849 seed-steps/s: stop it at any moment and run it again to continue. Finished runs are then
# copied to results/study (lava-bridge-bench export).
STUDY_STARTS := auxss,uniform_ss,omega_ss,goaldist_ss,reverse_ss
STUDY_BASELINES := sac,hysac_auxss
STUDY_SEEDS := 0-19
# A sweep puts LavaBridge-v0's runs straight under its --out (the other tasks' under OUT/TASK), so the
# reference task gets runs/study/LavaBridge-v0 as its --out: every task then has its own directory.
STUDY_SWEEP_OPTIONS := --eval-every 10000 --seeds-per-job 10 --workers 2 --threads 1
STUDY_SWEEP := $(BIN)/lava-bridge-bench sweep --seeds $(STUDY_SEEDS) $(STUDY_SWEEP_OPTIONS)
# After each export, results/study keeps only the episode logs its report reads: reverse_ss's
# (eval/analysis/report.py, LOG_READ_METHODS); every run's metrics and start weights stay.
STUDY_KEEP_LOGS := $(BIN)/python -m lava_bridge_mj.eval.training.compress results/study --keep-logs-of reverse_ss
study: setup
	$(STUDY_SWEEP) --methods $(STUDY_STARTS) --envs LavaBridgeDecoy-v0,LavaBridgeFarStart-v0 --steps 100000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_STARTS) --envs LavaBridgeTwoCrossings-v0 --steps 300000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_STARTS) --envs LavaBridgeNarrow-v0 --steps 100000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_STARTS) --envs LavaBridge-v0 --steps 100000 --out runs/study/LavaBridge-v0
	$(STUDY_SWEEP) --methods $(STUDY_BASELINES) \
	    --envs LavaBridgeDecoy-v0,LavaBridgeFarStart-v0,LavaBridgeNarrow-v0 --steps 100000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_BASELINES) --envs LavaBridge-v0 --steps 100000 --out runs/study/LavaBridge-v0
	$(STUDY_SWEEP) --methods $(STUDY_BASELINES) --envs LavaBridgeTwoCrossings-v0 --steps 300000 --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# The seed extension: after the first 20 seeds the study's table of answers asks for at most 46-49 seeds per
# group, so every group of a comparison still open trains seeds 20-48 (open: undecided, or
# decided at 0.05 only, not at the two-look level of STUDY_LOOKS): the four start distributions of the first
# question on every task, the reverse curriculum where the second is open (every task but the two
# crossings), the tasks with the largest undecided effects first, the two crossings' 300k groups last
# (a job there takes three times as long, so the 100k groups land first). SAC and HySAC+AuxSS, which no
# question compares, stay at 20. The report reads a task's extension once, when every one of its groups here
# has its 49 seeds (docs/design.md: a target, not a stopping rule): STUDY_REPORT_SEEDS. About 17 hours.
STUDY_EXTENSION_SEEDS := 20-48
# The seeds per group of the study's two readings: every verdict is also checked at Pocock's two-look level
STUDY_LOOKS := 20,49
# The seeds the study report reads: the study's and the extension's
STUDY_REPORT_SEEDS := 0-48
STUDY_EXTENSION := $(BIN)/lava-bridge-bench sweep --seeds $(STUDY_EXTENSION_SEEDS) $(STUDY_SWEEP_OPTIONS)
study-extension: setup
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss,reverse_ss --envs LavaBridgeDecoy-v0 \
	    --steps 100000 --out runs/study
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss,reverse_ss --envs LavaBridgeFarStart-v0 \
	    --steps 100000 --out runs/study
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss,reverse_ss --envs LavaBridgeNarrow-v0 \
	    --steps 100000 --out runs/study
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss,reverse_ss --envs LavaBridge-v0 \
	    --steps 100000 --out runs/study/LavaBridge-v0
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss --envs LavaBridgeTwoCrossings-v0 --steps 300000 --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# RFCL as published (rfcl: its reverse and forward curricula; rfcl_reverse: the reverse one alone) on every
# task of the suite, at the study's budgets, seeds and sweep options; the study's second question then reads
# AuxSS against rfcl on each task that has its runs (eval/analysis/study.py). 2 x 20 seeds x 700,000 steps = 28 M
# seed-steps, about 9 hours at the study's 849 seed-steps/s: `lava-bridge-bench train --method rfcl
# --env LavaBridge-v0 --seeds 0-9 --steps 2000 --eval-every 2000 --threads 1` used 33.2 CPU seconds, 602
# seed-steps per CPU second (set-up and one evaluation round included; CPU time, as the machine was loaded),
# and the same command with --method auxss 32.9, so rfcl costs what AuxSS does; two such jobs on the two
# cores give at most 1,204 seed-steps/s, 6.5 hours.
STUDY_RFCL := rfcl,rfcl_reverse
study-rfcl: setup
	$(STUDY_SWEEP) --methods $(STUDY_RFCL) --envs LavaBridgeDecoy-v0,LavaBridgeFarStart-v0,LavaBridgeNarrow-v0 \
	    --steps 100000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_RFCL) --envs LavaBridge-v0 --steps 100000 --out runs/study/LavaBridge-v0
	$(STUDY_SWEEP) --methods $(STUDY_RFCL) --envs LavaBridgeTwoCrossings-v0 --steps 300000 --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# RFCL's seed extension, the study's extension rule applied to its second question against rfcl: where that
# comparison is open at the first look (undecided, or decided at 0.05 only), rfcl trains seeds 20-48 (AuxSS,
# which the first question compares on every task, already has them). Only tasks whose rfcl runs are in
# results/study are named; a test names the others once their runs are in. Export a task's extension once
# all its seeds have finished: every group of results/study holds the seeds of one look (tested).
study-rfcl-extension: setup
	$(STUDY_EXTENSION) --methods rfcl --envs LavaBridgeDecoy-v0,LavaBridgeFarStart-v0,LavaBridgeNarrow-v0 \
	    --steps 100000 --out runs/study
	$(STUDY_EXTENSION) --methods rfcl --envs LavaBridge-v0 --steps 100000 --out runs/study/LavaBridge-v0
	$(STUDY_EXTENSION) --methods rfcl --envs LavaBridgeTwoCrossings-v0 --steps 300000 --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# The study on the external tasks (docs/external-tasks.md): the four start distributions of the study's
# first question, RFCL as published for its second, then SAC and HySAC+AuxSS, on both mazes, evaluation
# seeds 0-19 and the study's sweep options, each maze at the budget its screening picked
# (results/external_screening, doc_tables.screening_budget; a test ties these budgets to it).
EXTERNAL_STUDY_STARTS := auxss,uniform_ss,omega_ss,goaldist_ss,rfcl
study-external: setup
	$(STUDY_SWEEP) --methods $(EXTERNAL_STUDY_STARTS) --envs PointMaze_Medium-v3 --steps 75000 --out runs/study
	$(STUDY_SWEEP) --methods $(EXTERNAL_STUDY_STARTS) --envs PointMaze_Large-v3 --steps 125000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_BASELINES) --envs PointMaze_Medium-v3 --steps 75000 --out runs/study
	$(STUDY_SWEEP) --methods $(STUDY_BASELINES) --envs PointMaze_Large-v3 --steps 125000 --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# The external tasks' seed extension, the study's extension rule on their own first look (every group of
# both questions, rfcl among them, as they trained together): the groups of each comparison still open at
# seeds 0-19 (undecided, or decided at 0.05 only) train seeds 20-48. Only mazes whose study runs are in
# results/study are named; a test names the others once their runs are in. The study report reads a maze at
# seeds 0-19 (--task-seeds) until every group of its extension is exported.
study-external-extension: setup
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss --envs PointMaze_Medium-v3 --steps 75000 \
	    --out runs/study
	$(STUDY_EXTENSION) --methods auxss,uniform_ss,omega_ss,goaldist_ss --envs PointMaze_Large-v3 --steps 125000 \
	    --out runs/study
	$(BIN)/lava-bridge-bench export runs/study results/study
	$(STUDY_KEEP_LOGS)

# docs/results.md's tables and figures, regenerated from the committed metrics in results/ (no training):
# every method at the 100k protocol budget, AuxSS, SAC and Omega-SS at the paper's 300k, the AuxSS ablations,
# the start-strategy calibration on the tuning seeds (docs/calibration.md), and the task suite's screening
# (at 100k, and the two crossings extended to the paper's 300k), and the study's finished runs (make study;
# each task at the budget it was trained to, so no --budget), the far start's reverse curriculum and the medium
# maze's rfcl, each with and without its shortened time limit beside AuxSS (results/study_ablations). Then the
# generated parts of the docs and results/INDEX.md are rewritten from the committed data (eval/analysis/doc_tables.py).
report: setup
	$(BIN)/lava-bridge-bench report results/protocol --budget 100000 --out docs/report
	$(BIN)/lava-bridge-bench report results/protocol/auxss-d500 results/protocol/sac-d500 results/protocol/omega_ss-d500 \
	    results/protocol/uniform_ss-d500 results/protocol/goaldist_ss-d500 --seeds 0-4 \
	    --out docs/report_300k
	$(BIN)/lava-bridge-bench report results/protocol/auxss-d500 results/ablations --budget 100000 --seeds 0-4 \
	    --out docs/report_ablations
	$(BIN)/lava-bridge-bench report results/calibration/strategies --budget 100000 --seeds 100-104 \
	    --out docs/report_calibration
	$(BIN)/lava-bridge-bench report results/calibration/strategies/auxss_base results/calibration/strategies/auxss_delta001 \
	    results/calibration/strategies/auxss_sigma015 results/calibration/strategies/goaldist_base \
	    results/calibration/strategies/goaldist_growth101 --budget 100000 --seeds 100-114 --out docs/report_calibration_confirm
	$(BIN)/lava-bridge-bench report results/suite/screening --budget 100000 --seeds 100-104 --out docs/report_screening
	$(BIN)/lava-bridge-bench report results/suite/screening/LavaBridgeTwoCrossings-v0 --budget 300000 --seeds 100-104 \
	    --out docs/report_screening_300k
	$(BIN)/lava-bridge-bench report results/study --seeds $(STUDY_REPORT_SEEDS) --looks $(STUDY_LOOKS) \
	    --out docs/report_study
	$(BIN)/lava-bridge-bench report results/study/LavaBridgeFarStart-v0/auxss-d500 \
	    results/study/LavaBridgeFarStart-v0/reverse_ss-d500 results/study_ablations/LavaBridgeFarStart-v0 \
	    --seeds $(STUDY_SEEDS) --all-pairs --out docs/report_reverse_limit
	$(BIN)/lava-bridge-bench report results/study/PointMaze_Medium-v3/auxss-d500 \
	    results/study/PointMaze_Medium-v3/rfcl-d500 results/study_ablations/PointMaze_Medium-v3 \
	    --seeds $(STUDY_SEEDS) --all-pairs --out docs/report_rfcl_limit
	$(BIN)/python -m lava_bridge_mj.eval.analysis.doc_tables

# The plain episode logs (episodes.csv) under COMPRESS_DIRS rewritten in place as episodes.csv.gz, and the
# uncompressed start_weights.npz as compressed ones: the forms the trainer writes, each checked to hold
# what it replaces before the old file goes (eval/training/compress.py). The reports read both forms
# alike; safe to run again.
COMPRESS_DIRS ?= results
compress-results: setup
	$(BIN)/python -m lava_bridge_mj.eval.training.compress $(COMPRESS_DIRS)

setup: gl $(STAMP)

# Off-screen OpenGL through Mesa (software EGL/OSMesa) when no GL library is installed yet.
gl:
	@if ! ldconfig -p | grep -q 'libEGL.so.1' || ! ldconfig -p | grep -Eq 'libEGL_(mesa|nvidia)'; then \
	    if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	        echo "installing Mesa for off-screen rendering: $(MESA_PACKAGES)"; \
	        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(MESA_PACKAGES) >/dev/null; \
	    else \
	        echo "warning: no libEGL found; install $(MESA_PACKAGES) (Debian) for rendering; render tests will be skipped"; \
	    fi; \
	fi

# Headless Chromium for the test that opens the built documentation site (tests/test_docs_site.py), when missing.
browser:
	@if ! command -v chromium >/dev/null && ! command -v chromium-browser >/dev/null; then \
	    if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	        echo "installing Chromium for the documentation site's browser test"; \
	        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; \
	    else \
	        echo "warning: no chromium found; install chromium (Debian) for the documentation site's browser test, which is skipped without it"; \
	    fi; \
	fi

$(STAMP): setup.cfg pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# the CPU build of torch first: any other version would pull a multi-GB CUDA build
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e '.[test,plots,docs]'
	touch $(STAMP)

clean:
	rm -rf $(VENV) build site *.egg-info
