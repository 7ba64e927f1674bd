# Two entry points: `make demo` (the main job) and `make test` (the test suite). Both install the Debian packages
# they need first (apt), then build with CMake.
BUILD ?= build
JOBS ?= $(shell nproc)
DEMO ?= out/demo
CONFIG ?= configs/tiny.json
# The model `make demo` ends by offering to open in the viewer (`uplvsm serve`).
SERVE_CHECKPOINT ?= $(DEMO_MAPPER_MODEL)
UPLVSM = $(BUILD)/uplvsm
export CCACHE_SLOPPINESS = pch_defines,time_macros,include_file_mtime,include_file_ctime
export CCACHE_DIR ?= $(HOME)/.cache/ccache

# Why each package is there: README.md, "Dependencies".
APT_PACKAGES = cmake make g++ pkg-config ccache libtorch-dev libopenblas0-openmp libgloo-dev libcli11-dev \
  nlohmann-json3-dev libspdlog-dev libfmt-dev libjpeg62-turbo-dev libpng-dev libavcodec-dev libavformat-dev \
  libavutil-dev libswscale-dev libexif-dev libgtest-dev libbenchmark-dev libcpp-httplib-dev python3-dev \
  python3-pybind11 python3-torch python3-pytest

# The viewer's browser test (tests/browser) drives Debian's chromium from Node.js (installed from Debian when the
# machine has no node/npm) with playwright-core from the committed lock file; only `make test` installs them.
BROWSER_APT_PACKAGES = chromium $(shell command -v npm >/dev/null || echo nodejs npm)

# The fuzz targets need clang and its libFuzzer runtime (only `make fuzz` installs them).
FUZZ_APT_PACKAGES = clang libclang-rt-14-dev
FUZZ_BUILD ?= build-fuzz
FUZZ_SECONDS ?= 60

# The sanitizer build (README "Robustness"): library, CLI and unit tests with AddressSanitizer + UBSan.
SAN_BUILD ?= build-sanitize
SAN_LAYERS ?= core io geometry data render serve
export ASAN_OPTIONS ?= detect_leaks=0:alloc_dealloc_mismatch=0:abort_on_error=0:strict_string_checks=1
export UBSAN_OPTIONS ?= print_stacktrace=1:halt_on_error=1

# C++ formatting (.clang-format: Google style, 120 columns) with Debian's clang-format 14: `make format` applies it,
# `make lint` checks it without changing anything (CI runs it).
LINT_APT_PACKAGES = clang-format-14 git
CLANG_FORMAT ?= clang-format-14
FORMATTED_SOURCES = $(shell git ls-files -- 'src/*.cpp' 'src/*.h' 'tests/*.cpp' 'tests/*.h' 'bench/*.cpp' 'bench/*.h' \
  'python/src/*.cpp' 'python/src/*.h' 'fuzz/*.cpp' 'examples/*.cpp' 2>/dev/null)

.PHONY: all deps browser-deps build build-cli python install test test-unit test-slow bench demo demo-model demo-ceiling-model fuzz sanitize clean format lint

all: build

deps:
	@missing=$$(for p in $(APT_PACKAGES) $(EXTRA_APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing:" $$missing; \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q --no-install-recommends $$missing; \
	fi

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

# The demo needs only the binary, not the test programs.
build-cli: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS) --target uplvsm_cli

# The Python module alone (also part of `build`): import it with PYTHONPATH=$(BUILD)/python.
python: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS) --target uplvsm_python

# The binary, libuplvsm.so, headers, configs, the CMake package and the Python module under PREFIX (docs/cpp.md).
PREFIX ?= /usr/local
install: build
	cmake --install $(BUILD) --prefix $(PREFIX)

browser-deps:
	$(MAKE) deps EXTRA_APT_PACKAGES="$(BROWSER_APT_PACKAGES)"
	cd tests/browser && npm ci --no-audit --no-fund

# Tests run JOBS at a time (each picks free loopback ports and its own temporary folders).
test: build browser-deps
	cd $(BUILD) && ctest --output-on-failure --timeout 1800 -j $(JOBS)

test-unit: build
	cd $(BUILD) && ctest --output-on-failure -L unit -j $(JOBS)

test-slow: build browser-deps
	cd $(BUILD) && ctest --output-on-failure -L slow -j $(JOBS)

# Benchmarks, as the environment is and without this machine's OPENBLAS_* overrides (see README, Performance); then
# the x224 forward from Python beside the same forward from C++ (bench/python_vs_cpp.py), both ways too.
# BENCH_PYTHON=0 leaves the Python comparison out.
BENCH_PYTHON ?= 1
PYTHON_BENCH = PYTHONPATH=$(BUILD)/python /usr/bin/python3 bench/python_vs_cpp.py --build $(BUILD)
bench: build
	$(BUILD)/uplvsm_bench $(BENCH_ARGS)
	env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE $(BUILD)/uplvsm_bench $(BENCH_ARGS)
	if [ "$(BENCH_PYTHON)" = 1 ]; then $(PYTHON_BENCH) && env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE $(PYTHON_BENCH); fi

# libFuzzer on every reader of untrusted files (fuzz/; README "Robustness"): FUZZ_SECONDS per target, from the seeds
# in fuzz/corpus/<name>; new inputs accumulate in $(FUZZ_BUILD)/corpus/<name>, crashes are written to $(FUZZ_BUILD)/
# and fail the target. Executions per target go to $(FUZZ_BUILD)/fuzz_summary.txt. FUZZ_ONLY=image runs one.
FUZZ_TARGETS = chunk:fuzz_chunk_reader json:fuzz_json_readers safetensors:fuzz_safetensors torch_file:fuzz_torch_file \
  image:fuzz_image camera_path:fuzz_camera_path config:fuzz_config
FUZZ_ONLY ?=
fuzz:
	$(MAKE) deps EXTRA_APT_PACKAGES="$(FUZZ_APT_PACKAGES)"
	test -f $(FUZZ_BUILD)/CMakeCache.txt || CXX=clang++ cmake -S fuzz -B $(FUZZ_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo
	cmake --build $(FUZZ_BUILD) -j $(JOBS)
	rm -f $(FUZZ_BUILD)/fuzz_summary.txt
	cd $(FUZZ_BUILD) && for t in $(FUZZ_TARGETS); do \
	  name=$${t%%:*}; bin=$${t#*:}; \
	  if [ -n "$(FUZZ_ONLY)" ] && [ "$(FUZZ_ONLY)" != "$$name" ]; then continue; fi; \
	  mkdir -p corpus/$$name; \
	  ASAN_OPTIONS=detect_leaks=0:alloc_dealloc_mismatch=0 ./$$bin -max_total_time=$(FUZZ_SECONDS) -timeout=10 \
	    -rss_limit_mb=4096 -malloc_limit_mb=1024 -max_len=65536 -print_final_stats=1 corpus/$$name $(CURDIR)/fuzz/corpus/$$name \
	    > $$name.log 2>&1; \
	  status=$$?; \
	  echo "$$bin: $$(grep -o 'number_of_executed_units: [0-9]*' $$name.log | grep -o '[0-9]*') executions in" \
	    "$(FUZZ_SECONDS) s, exit status $$status" | tee -a fuzz_summary.txt; \
	  [ $$status -eq 0 ] || { tail -40 $$name.log; exit 1; }; \
	done

# A second build of the unit tests of SAN_LAYERS with -fsanitize=address,undefined (-O1 -g), each test binary run
# directly (ctest's labels cannot name a layer: gtest_discover_tests flattens a list of labels); any report fails
# its test and the target. SAN_TEST_ARGS=--gtest_filter=... narrows them. cli (its tests mostly run the CLI
# binary) and the model/train/eval/study layers (LibTorch compute, which the sanitizers do not instrument) are left out
# for CI's time; the readers of untrusted files and the HTTP server are in the layers above.
sanitize: deps
	test -f $(SAN_BUILD)/CMakeCache.txt || cmake -S . -B $(SAN_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DUPLVSM_SANITIZE=address,undefined,float-cast-overflow \
	  -DUPLVSM_BUILD_BENCHMARKS=OFF
	cmake --build $(SAN_BUILD) -j $(JOBS) --target $(addprefix test_,$(SAN_LAYERS))
	cd $(SAN_BUILD) && for layer in $(SAN_LAYERS); do \
	  echo "sanitize: test_$$layer"; ./test_$$layer --gtest_brief=1 $(SAN_TEST_ARGS) || exit 1; \
	done

# The shipped demo models (models/, trained by `uplvsm train`: `make demo-model` below and docs/demo.md "The shipped
# demo model") are evaluated and rendered on held-out scenes at their resolution, beside LVSM of the same width told
# every camera (the ceiling the unposed model is measured against); the `tiny` config is trained from scratch beside
# them (proof that training works on this machine); one report shows them side by side.
DEMO_MODEL ?= models/demo.safetensors
DEMO_MAPPER_MODEL ?= models/demo_mapper.safetensors
DEMO_CEILING_MODEL ?= models/demo_lvsm.safetensors
DEMO_MODEL_CONFIG ?= configs/demo_model_stage1.json
# Camera control for the shipped model without fine-tuning it (uplvsm fit-mapper), fitted by make demo.
DEMO_FITTED_MAPPER = $(DEMO)/fitted_mapper/mapper.safetensors
DEMO_RENDER = --data $(DEMO)/dataset_demo --split test --scenes 3 --frames 48 --side-by-side
demo: build-cli
	$(UPLVSM) info
	test -f $(DEMO)/dataset_demo/evaluation_index.json || $(UPLVSM) make-dataset --config $(DEMO_MODEL_CONFIG) --train-scenes 0 --out $(DEMO)/dataset_demo
	$(UPLVSM) eval --checkpoint $(DEMO_MODEL) --data $(DEMO)/dataset_demo --split test --out $(DEMO)/shipped/eval
	$(UPLVSM) render --checkpoint $(DEMO_MODEL) $(DEMO_RENDER) --out $(DEMO)/shipped/interpolation
	$(UPLVSM) eval --checkpoint $(DEMO_MAPPER_MODEL) --data $(DEMO)/dataset_demo --split test --target-poses mapper --jitter --out $(DEMO)/shipped_mapper/eval
	$(UPLVSM) render --checkpoint $(DEMO_MAPPER_MODEL) $(DEMO_RENDER) --trajectory orbit --out $(DEMO)/shipped_mapper/orbit
	$(UPLVSM) eval --checkpoint $(DEMO_CEILING_MODEL) --data $(DEMO)/dataset_demo --split test --out $(DEMO)/ceiling/eval
	$(UPLVSM) render --checkpoint $(DEMO_CEILING_MODEL) $(DEMO_RENDER) --out $(DEMO)/ceiling/interpolation
	test -f $(DEMO)/dataset/evaluation_index.json || $(UPLVSM) make-dataset --config $(CONFIG) --out $(DEMO)/dataset
	test -f $(DEMO_FITTED_MAPPER) || $(UPLVSM) fit-mapper --checkpoint $(DEMO_MODEL) --data $(DEMO)/dataset --out $(DEMO_FITTED_MAPPER)
	$(UPLVSM) eval --checkpoint $(DEMO_MODEL) --mapper $(DEMO_FITTED_MAPPER) --data $(DEMO)/dataset_demo --split test --jitter --out $(DEMO)/fitted_mapper/eval
	$(UPLVSM) render --checkpoint $(DEMO_MODEL) --mapper $(DEMO_FITTED_MAPPER) $(DEMO_RENDER) --trajectory orbit --out $(DEMO)/fitted_mapper/orbit
	$(UPLVSM) train --config $(CONFIG) --data $(DEMO)/dataset --run $(DEMO)/run --resume auto
	$(UPLVSM) eval --checkpoint $(DEMO)/run --data $(DEMO)/dataset --split test --out $(DEMO)/eval
	$(UPLVSM) render --checkpoint $(DEMO)/run --data $(DEMO)/dataset --split test --side-by-side --out $(DEMO)/video
	$(UPLVSM) report --title "uplvsm demo" --out $(DEMO)/report \
	  --model "label=Shipped demo model ($(DEMO_MODEL)),eval=$(DEMO)/shipped/eval,video=$(DEMO)/shipped/interpolation,caption=UP-LVSM at 96x96 trained by uplvsm train on the built-in rooms with the rotation-first recipe (configs/demo_model_stage1.json: 4000 steps x 8 with a rotation-only latent camera on 2 CPU cores; then configs/demo_model_stage2_gpu.json: 4000 steps x 32 with the full camera on a GPU; then configs/demo_model_stage3.json: 1500 steps x 8 with the gradient difference loss against the blur on 2 CPU cores; then configs/demo_model_stage4_gpu.json: 2000 steps x 32 with the same loss on a GPU); unposed: target poses from the Latent Plücker Learner; the encoder also reads the inputs' latent cameras and the decoder the input images' tokens; video: interpolation between the two inputs' latent poses; held-out scenes" \
	  --model "label=Shipped model with camera control ($(DEMO_MAPPER_MODEL)),eval=$(DEMO)/shipped_mapper/eval,video=$(DEMO)/shipped_mapper/orbit,caption=the same after the camera-mapper fine-tune (configs/demo_model_mapper.json); targets rendered from their real cameras through the linear mapper; video: an explicit orbit around the scene" \
	  --model "label=The shipped model with a fitted mapper ($(DEMO_MODEL) + fit-mapper),eval=$(DEMO)/fitted_mapper/eval,video=$(DEMO)/fitted_mapper/orbit,caption=camera control without fine-tuning: uplvsm fit-mapper fitted an MLP pose mapper (reading the inputs' latent poses) to the frozen shipped model on this demo's 400 training rooms in minutes; targets rendered from their real cameras through it; video: the same orbit" \
	  --model "label=With known cameras: the ceiling ($(DEMO_CEILING_MODEL)),eval=$(DEMO)/ceiling/eval,video=$(DEMO)/ceiling/interpolation,caption=LVSM of the same width (decoder-only; configs/demo_ceiling_gpu.json) told every camera in training and at test: what a perfect latent camera could approach; trained on the unposed model's budget (5375 steps x 32 = 172000 scenes of 6 targets; one GPU); video: interpolation between the inputs' real cameras" \
	  --model "label=tiny trained here from scratch ($(CONFIG)),run=$(DEMO)/run,eval=$(DEMO)/eval,video=$(DEMO)/video,caption=the same model family at 48x48 trained by this make demo"
	@echo "interactive viewer: $(UPLVSM) serve --checkpoint $(SERVE_CHECKPOINT) --data $(DEMO)/dataset_demo  (then open http://127.0.0.1:8080/)"

# Reproduces the shipped demo models from scratch with our own trainer: the built-in 96x96 rooms, the rotation-first
# recipe's first stage (configs/demo_model_stage1.json: 4000 steps at batch 8 with a rotation-only latent camera; 2 CPU
# cores, ~78 min at one thread, the thread count it was trained with: bf16 sums split across threads round
# differently), its second stage with the full latent camera (configs/demo_model_stage2_gpu.json: 4000 steps
# at batch 32; one H200, 330 s), a third stage that adds the gradient difference loss against the blur
# (configs/demo_model_stage3.json: 1500 steps at batch 8; 2 CPU cores, ~27 min at one thread), a fourth with
# more compute and the same loss (configs/demo_model_stage4_gpu.json: 2000 steps at batch 32; one H200,
# 170 s), the camera-mapper fine-tune with the same loss (configs/demo_model_mapper.json, 2000 steps at
# batch 8; 2 CPU cores), then the weights-only exports. DEMO_MODEL_DEVICE=cpu runs the second and fourth stages on a
# CPU too (hours on 2 cores). Every step resumes, so run it again after an interruption.
DEMO_MODEL_WORK ?= out/demo_model
DEMO_MODEL_DEVICE ?= cuda
DEMO_FIRST_STAGE_DEVICE ?= cpu
DEMO_FIRST_STAGE_THREADS ?= 1
DEMO_SHARPEN_DEVICE ?= cpu
DEMO_SHARPEN_THREADS ?= 1
DEMO_MAPPER_DEVICE ?= cpu
demo-model: build-cli
	test -f $(DEMO_MODEL_WORK)/data/evaluation_index.json || $(UPLVSM) make-dataset --config $(DEMO_MODEL_CONFIG) --out $(DEMO_MODEL_WORK)/data
	$(UPLVSM) train --config $(DEMO_MODEL_CONFIG) --data $(DEMO_MODEL_WORK)/data --run $(DEMO_MODEL_WORK)/rotation \
	  --resume auto --device $(DEMO_FIRST_STAGE_DEVICE) --threads $(DEMO_FIRST_STAGE_THREADS)
	$(UPLVSM) train --config configs/demo_model_stage2_gpu.json --init $(DEMO_MODEL_WORK)/rotation --data $(DEMO_MODEL_WORK)/data \
	  --run $(DEMO_MODEL_WORK)/main --resume auto --device $(DEMO_MODEL_DEVICE)
	$(UPLVSM) train --config configs/demo_model_stage3.json --init $(DEMO_MODEL_WORK)/main --data $(DEMO_MODEL_WORK)/data \
	  --run $(DEMO_MODEL_WORK)/sharp --resume auto --device $(DEMO_SHARPEN_DEVICE) --threads $(DEMO_SHARPEN_THREADS)
	$(UPLVSM) train --config configs/demo_model_stage4_gpu.json --init $(DEMO_MODEL_WORK)/sharp --data $(DEMO_MODEL_WORK)/data \
	  --run $(DEMO_MODEL_WORK)/long --resume auto --device $(DEMO_MODEL_DEVICE)
	$(UPLVSM) train --stage mapper --config configs/demo_model_mapper.json --init $(DEMO_MODEL_WORK)/long --data $(DEMO_MODEL_WORK)/data \
	  --run $(DEMO_MODEL_WORK)/mapper --resume auto --device $(DEMO_MAPPER_DEVICE)
	$(UPLVSM) export --checkpoint $(DEMO_MODEL_WORK)/long --out $(DEMO_MODEL)
	$(UPLVSM) export --checkpoint $(DEMO_MODEL_WORK)/mapper --out $(DEMO_MAPPER_MODEL)

# Reproduces the shipped ceiling (LVSM told every camera, configs/demo_ceiling_gpu.json: the unposed model's
# budget up to its third stage, 5375 steps at batch 32 of 6 targets = 172000 scenes; one H200, 430 s).
demo-ceiling-model: build-cli
	test -f $(DEMO_MODEL_WORK)/data/evaluation_index.json || $(UPLVSM) make-dataset --config $(DEMO_MODEL_CONFIG) --out $(DEMO_MODEL_WORK)/data
	$(UPLVSM) train --config configs/demo_ceiling_gpu.json --data $(DEMO_MODEL_WORK)/data --run $(DEMO_MODEL_WORK)/ceiling \
	  --resume auto --device $(DEMO_MODEL_DEVICE)
	$(UPLVSM) export --checkpoint $(DEMO_MODEL_WORK)/ceiling --out $(DEMO_CEILING_MODEL)

clean:
	rm -rf $(BUILD) $(FUZZ_BUILD) $(SAN_BUILD)

format:
	$(MAKE) deps EXTRA_APT_PACKAGES="$(LINT_APT_PACKAGES)"
	$(CLANG_FORMAT) -i $(FORMATTED_SOURCES)

lint:
	$(MAKE) deps EXTRA_APT_PACKAGES="$(LINT_APT_PACKAGES)"
	@$(CLANG_FORMAT) --dry-run -Werror $(FORMATTED_SOURCES)
	@echo "lint: $(words $(FORMATTED_SOURCES)) files formatted as .clang-format says"
	@python3 tools/check_fuzz_sources.py
	@python3 tools/check_layers.py
	@! grep -rn --include='*.cpp' --include='*.h' 'remove_all(' src tests | grep -v 'tests/test_util.h' || \
	  { echo "lint: use test::remove_tree (tests/test_util.h): std::filesystem::remove_all crashes under PyPI's LibTorch 2.11"; exit 1; }
