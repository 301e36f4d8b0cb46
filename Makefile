# Two commands for a new user: `make demo` and `make test`. Both set everything up first.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.installed

.PHONY: setup llvm test test-fast demo best generalist building lint bench contact-sheet clean

setup: $(STAMP)

# libLLVM >= 16 lets Mitsuba use its fast llvm_ad_rgb variant; without it the code falls
# back to scalar_rgb with a warning, so a failed install is not fatal.
llvm:
	@if ls /usr/lib/*/libLLVM-19.so* /usr/lib/*/libLLVM.so.19* >/dev/null 2>&1; then \
	  echo "libLLVM 19 present"; \
	elif [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null; then \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19) \
	    || echo "warning: could not install libllvm19; rendering will use scalar_rgb (slower)"; \
	else \
	  echo "warning: libllvm19 missing and not root; rendering will use scalar_rgb (slower)"; \
	fi

$(STAMP): pyproject.toml
	$(MAKE) llvm
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q torch==2.14.1 torchvision==0.29.1
	$(PIP) install -q -e '.[dev,ros,viz]'
	touch $(STAMP)

test: setup
	$(PY) -m pytest -q

test-fast: setup
	$(PY) -m pytest -q -m "not slow"

# ruff check (pyproject.toml); `ruff format` is not enforced: datagen/ and localize/ keep a
# denser hand layout than the formatter's.
lint: setup
	$(VENV)/bin/ruff check .

# The whole pipeline on its default, small config: datagen -> train -> localize, in at most
# DEMO_MINUTES (30), set-up included: the SegNet trains until DEMO_RESERVE_S seconds before the
# end (for its test and export, ~0.5 min, and localize, 2.4-4 min), at most conf/train.yaml's
# max_minutes (18), with its schedule shortened to fit, but never less than
# DEMO_MIN_TRAIN_MINUTES (12): where set-up and datagen leave less, the demo runs over rather
# than show a SegNet too short to track (docs/train.md). `make demo DEMO_MINUTES=` trains the
# full max_minutes whatever the clock.
DEMO_MINUTES ?= 30
DEMO_MIN_TRAIN_MINUTES ?= 12
DEMO_RESERVE_S ?= 330
DEMO_START := $(shell date +%s)
# Unix time the SegNet stops by: the demo's end less the reserve, but no sooner than the floor.
DEMO_END = ($(DEMO_START) + $(DEMO_MINUTES) * 60 - $(DEMO_RESERVE_S))
DEMO_FLOOR = ($$(date +%s) + $(DEMO_MIN_TRAIN_MINUTES) * 60)
demo: setup
	$(PY) -m datagen
	$(PY) -m train$(if $(DEMO_MINUTES), finish_by=$$(( $(DEMO_END) > $(DEMO_FLOOR) ? $(DEMO_END) : $(DEMO_FLOOR) )))
	$(PY) -m localize
	@echo "report: outputs/reports/demo/report.md"

# The best SegNet: the recipe chain of conf/experiment/ (best1_fullres -> best2_unweighted ->
# best3_highres -> best4_highres_longer -> best5_context, each stage starting from the
# previous one's weights; about 6 hours on 2 cores) on the demo's dataset, then localize with
# it: its model folder carries the localize settings it is tuned for (docs/recipes.md).
# Interrupted, `make best` again resumes where it stopped.
BEST_CHAIN := best1_fullres best2_unweighted best3_highres best4_highres_longer best5_context
best: setup
	$(PY) -m datagen
	set -e; for stage in $(BEST_CHAIN); do $(PY) -m train experiment=$$stage; done
	$(PY) -m localize name=best onnx_model=outputs/models/best5_context/segnet.onnx
	@echo "report: outputs/reports/best/report.md"

# The generalist SegNet, for buildings it never saw (docs/recipes.md, "Remaking the
# generalist"): 48 procedural floors (~2 h; `hydra/launcher=ray` or `slurm` spreads them),
# then 40 epochs of training (~2.5 h; the epochs bound it, no time budget), each epoch logged
# with the time left. Stopped anyhow (kill -9, a new session), `make generalist` again
# continues: datagen renders only the frames missing, training resumes after its last finished
# epoch with the same schedule and counts the time already trained. It writes
# outputs/models/generalist/; benchmarks/promote.py copies it into models/generalist/ only
# when it tracks better on every third-party building and not worse in the corridor.
generalist: setup
	$(PY) -m datagen -m datagen_experiment=generalist_floors
	$(PY) -m train experiment=generalist

# Your building, the recommended path (docs/recipes.md, "The generalist, then the fine-tune"): a whole floor of a
# model file rendered (docs/importers.md; .world/.sdf, .glb/.gltf, .obj, .ply, .dae, .stl,
# .ifc) with two ~45 m flights along routes planned through its free space
# (conf/flights/floor.yaml); the shipped generalist SegNet (models/generalist/) fine-tuned on it
# for 9 epochs (conf/experiment/finetune.yaml, ~9 min on 2 cores) into outputs/models/NAME/,
# whose segnet.onnx is the generalist's network where the building's validation renders show
# the fine-tune no gain (docs/recipes.md, "A fine-tune that never hurts"); then localize with
# that folder's model: `make building BUILDING=path/to/model.world NAME=hospital`.
NAME ?= building
building: setup
	@test -n "$(BUILDING)" || { echo "give BUILDING=path/to/model (.world .sdf .glb .gltf .obj .ply .dae .stl .ifc)"; exit 2; }
	@echo "1/3 datagen: render $(BUILDING) into outputs/datasets/$(NAME)"
	$(PY) -m datagen name=$(NAME) world=file world.path=$(BUILDING) flights=floor
	@echo "2/3 train: fine-tune the shipped generalist (models/generalist) on it, 9 epochs, into outputs/models/$(NAME) (the generalist kept where the fine-tune gains nothing)"
	$(PY) -m train experiment=finetune name=$(NAME) dataset=outputs/datasets/$(NAME)
	@echo "3/3 localize: the flights of outputs/datasets/$(NAME) with outputs/models/$(NAME)/segnet.onnx"
	$(PY) -m localize name=$(NAME) dataset=outputs/datasets/$(NAME) onnx_model=outputs/models/$(NAME)/segnet.onnx
	@echo "report: outputs/reports/$(NAME)/report.md"

contact-sheet: setup
	$(PY) -m datagen.contact_sheet outputs/datasets/demo docs/img/contact_sheet.png

# Speed and accuracy figures; those after render_building read the demo's outputs (run `make demo` first).
bench: setup
	$(PY) benchmarks/datagen_throughput.py
	$(PY) benchmarks/render_building.py  # an imported building (the AWS hospital, if ../shared has it)
	-$(PY) benchmarks/train_accuracy.py outputs/models/demo  # exits 1 when a target is missed
	$(PY) benchmarks/segnet_speed.py
	$(PY) benchmarks/localize_speed.py
	$(PY) benchmarks/paper_faithful.py   # the paper's render-per-particle likelihood against the vectorized one
	$(PY) benchmarks/boundary_distance.py
	$(PY) benchmarks/flight_spread.py   # 3 new flights per preset and the demo's own 2: the accuracy over 8 flights (~12 min)
	$(PY) benchmarks/dropout_recovery.py   # 2 s camera dropouts on the demo's flights: back within 0.3 m in 3 s? (~8 min)

clean:
	rm -rf outputs multirun
