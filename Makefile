# clod_haptics: `make demo` runs the main job, `make test` every test. Both install what is missing
# (Debian 12 packages), build in a catkin workspace under .build and keep logs there.
SHELL := /bin/bash
ROOT := $(CURDIR)
BUILD := $(ROOT)/.build
WS := $(BUILD)/ws
JOBS ?= 2
# The login python3 may be a pyenv one without ROS modules: catkin, rostest and dynparam need Debian's.
export PATH := /usr/bin:/bin:$(PATH)
export PYENV_VERSION := system
export ROS_HOME := $(BUILD)/ros_home
export ROS_LOG_DIR := $(BUILD)/ros_home/log

# Debian packages the package needs (ROS 1 from Debian, no /opt/ros).
APT_ROS := ros-base-dev python3-dynamic-reconfigure python3-rostest rosbash libtf2-ros-dev libgtest-dev \
  libeigen3-dev libassimp-dev rviz python3-geometry-msgs python3-visualization-msgs
APT_SCREENSHOT := xvfb xauth imagemagick
APT_BENCH := libcgal-dev libfcl-dev libembree-dev libbenchmark-dev python3-matplotlib python3-numpy

CATKIN := cd $(WS) && catkin_make -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=Release $(CMAKE_EXTRA) --make-args
SETUP := source $(WS)/devel/setup.bash
TOOL := $(WS)/devel/lib/clod_haptics/clod_tool
DEMO_MESH := $(ROOT)/data/meshes/torus.obj

.PHONY: all deps deps-screenshot deps-bench build test demo demo-core clean bench

all: build

# Installs only the packages that are missing; apt-get update only when something is.
define apt_install
	@missing=$$(for p in $(1); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  echo "installing:" $$missing; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	fi
endef

deps:
	$(call apt_install,$(APT_ROS))

deps-screenshot:
	$(call apt_install,$(APT_SCREENSHOT))

deps-bench:
	$(call apt_install,$(APT_BENCH))

# Benchmark (bench/): its own workspace configured with CLOD_BUILD_BENCH=ON, so `make test` keeps
# the default OFF. Full run (< 30 min) writes bench/results/ (report.md, CSV, PNG);
# BENCH_QUICK=1 is a few minutes and writes bench/results/tmp/quick/. BENCH_ARGS passes options
# to clod_bench, e.g. BENCH_ARGS="--meshes mannequin-devil.off --sections sweep,peers".
BENCH_WS := $(BUILD)/bench_ws
BENCH_SHARED_DIR ?= $(if $(CLOD_SHARED_DIR),$(CLOD_SHARED_DIR),$(abspath $(ROOT)/../shared))
BENCH_QUICK_ON := $(filter-out 0 no false,$(BENCH_QUICK))
BENCH_OUT := $(if $(BENCH_QUICK_ON),$(ROOT)/bench/results/tmp/quick,$(ROOT)/bench/results)
bench: deps deps-bench
	@mkdir -p $(BENCH_WS)/src $(ROS_HOME) $(BENCH_OUT) && ln -sfn $(ROOT) $(BENCH_WS)/src/clod_haptics
	@echo "== building clod_bench in $(BENCH_WS) (log: $(BUILD)/bench_build.log) =="
	@cd $(BENCH_WS) && catkin_make clod_bench -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=Release \
	  -DCLOD_BUILD_BENCH=ON -DCATKIN_ENABLE_TESTING=OFF > $(BUILD)/bench_build.log 2>&1 || \
	  { tail -40 $(BUILD)/bench_build.log; exit 1; }
	@$(BENCH_WS)/devel/lib/clod_haptics/clod_bench --shared $(BENCH_SHARED_DIR) --out $(BENCH_OUT) \
	  $(if $(BENCH_QUICK_ON),--quick) $(BENCH_ARGS) 2>&1 | tee $(BUILD)/bench_run.log; exit $${PIPESTATUS[0]}
	@python3 $(ROOT)/bench/report.py $(BENCH_OUT)
	@echo "== report: $(BENCH_OUT)/report.md =="

$(WS)/src/clod_haptics:
	@mkdir -p $(WS)/src $(ROS_HOME)
	@ln -sfn $(ROOT) $(WS)/src/clod_haptics

build: deps $(WS)/src/clod_haptics
	@$(CATKIN) all

test: deps $(WS)/src/clod_haptics
	@$(CATKIN) all tests
	@rm -rf $(WS)/build/test_results
	@$(SETUP) && cd $(WS) && catkin_make -j1 run_tests > $(BUILD)/run_tests.log 2>&1; \
	  grep -E '^\[ +(OK|FAILED|SKIPPED) +\]|RESULT:|FAILURE|ERROR' $(BUILD)/run_tests.log | grep -v '^\[ *OK' | tail -60 || true
	@$(SETUP) && python3 $(ROOT)/scripts/count_test_results.py $(WS)/build/test_results

# The whole pipeline, headless: bag_replay plays the bundled stylus bag (data/bags/torus_stylus.bag,
# 7.5 s at 1 kHz) once over the bundled torus, sphere_builder + detector answer every pose, and
# scripts/contact_summary.py prints poses, contacts and the achieved rate, then stops the launch
# (exit 1 if poses went unanswered or the replay did not end). Its own master on a free port;
# the launch log goes to .build/demo.log.
demo: build
	@echo "== clod_haptics demo: bundled stylus bag -> bag_replay -> detector over $(DEMO_MESH) (log: $(BUILD)/demo.log) =="
	@port=$${DEMO_PORT:-$$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')} && \
	  $(SETUP) && export ROS_MASTER_URI=http://localhost:$$port CLOD_BAG_WAIT_FOR_SUBSCRIBERS=2 && \
	  timeout -k 10 180 python3 $(ROOT)/scripts/contact_summary.py --timeout 150 --log $(BUILD)/demo.log -- \
	  roslaunch -p $$port clod_haptics clod_haptics.launch device:=bag rviz:=false

# The core alone, no ROS master: a CLOD sweep of the bundled mesh.
demo-core: build
	@echo "== clod_haptics core demo: CLOD sweep of the bundled mesh ($(DEMO_MESH)) =="
	@$(TOOL) sweep --mesh $(DEMO_MESH) --normalize --distances 0,0.01,0.02,0.03,0.04,0.05,0.06,0.07,0.08

# RViz under a virtual X server (xvfb-run), the pipeline on the bundled torus with a stylus pose that
# touches it, the screen grabbed with ImageMagick's import: .build/screenshot.png (log beside it).
.PHONY: screenshot
screenshot: build deps-screenshot
	@$(SETUP) && $(ROOT)/scripts/screenshot.sh $(BUILD)/screenshot.png

clean:
	rm -rf $(BUILD)
