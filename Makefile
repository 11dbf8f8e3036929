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
  libeigen3-dev libassimp-dev rviz python3-geometry-msgs python3-visualization-msgs catkin-lint \
  libinteractive-markers-dev
# Python modules the tests, the demo and the scripts import beyond ROS (scripts/soak.py, which
# test/rostest/soak_short.test runs: numpy). `../shared/tools/check-deps` checks that nothing is missing.
APT_PYTHON := python3-numpy
APT_SCREENSHOT := xvfb xauth imagemagick
APT_BENCH := libcgal-dev libfcl-dev libembree-dev libbenchmark-dev python3-matplotlib python3-numpy

CATKIN := cd $(WS) && catkin_make -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=Release $(CMAKE_EXTRA) --make-args
# INSTALL=1: `make build` also installs (catkin_make install: .build/ws/install), and `make demo`, `make demo-core`
# run from that install space instead of the devel space.
INSTALL_ON := $(filter-out 0 no false,$(INSTALL))
SPACE := $(WS)/$(if $(INSTALL_ON),install,devel)
SETUP := source $(SPACE)/setup.bash
TOOL := $(SPACE)/lib/clod_haptics/clod_tool
CONTACT_SUMMARY := $(if $(INSTALL_ON),$(SPACE)/lib/clod_haptics/contact_summary.py,$(ROOT)/scripts/contact_summary.py)
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
	$(call apt_install,$(APT_ROS) $(APT_PYTHON))

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
	@mkdir -p $(BENCH_OUT)
	$(call link_package,$(BENCH_WS))
	@echo "== building clod_bench in $(BENCH_WS) (log: $(BUILD)/bench_build.log) =="
	@cd $(BENCH_WS) && catkin_make clod_bench -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=Release \
	  -DCLOD_BUILD_BENCH=ON -DCATKIN_ENABLE_TESTING=OFF > $(BUILD)/bench_build.log 2>&1 || \
	  { tail -40 $(BUILD)/bench_build.log; exit 1; }
	@$(BENCH_WS)/devel/lib/clod_haptics/clod_bench --shared $(BENCH_SHARED_DIR) --out $(BENCH_OUT) \
	  $(if $(BENCH_QUICK_ON),--quick) $(BENCH_ARGS) 2>&1 | tee $(BUILD)/bench_run.log; exit $${PIPESTATUS[0]}
	@python3 $(ROOT)/bench/report.py $(BENCH_OUT)
	@echo "== report: $(BENCH_OUT)/report.md =="

# Scene benchmark: 50 objects, 1.9 M triangles; start-up from the level cache against
# building, query cost near one object in the scene against that object alone. Core only, no peers.
SCENE_BENCH_WS := $(BUILD)/scene_bench_ws
.PHONY: scene-bench
scene-bench: deps
	$(call link_package,$(SCENE_BENCH_WS))
	@cd $(SCENE_BENCH_WS) && catkin_make scene_bench -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=Release \
	  -DCLOD_BUILD_SCENE_BENCH=ON -DCATKIN_ENABLE_TESTING=OFF > $(BUILD)/scene_bench_build.log 2>&1 || \
	  { tail -40 $(BUILD)/scene_bench_build.log; exit 1; }
	@$(SCENE_BENCH_WS)/devel/lib/clod_haptics/scene_bench --shared $(BENCH_SHARED_DIR) $(SCENE_BENCH_ARGS) 2>&1 | \
	  tee $(BUILD)/scene_bench_run.log; exit $${PIPESTATUS[0]}

# A workspace's src/clod_haptics links $(PKG_DIR), a directory holding a link to each top-level entry of the
# repository except .build and .git: the package root seen by catkin, rospack, rosrun and roslaunch then does
# not contain the workspace, so `find -L` (rosrun) walks the package once, with no "File system loop".
# package.xml and nodelet_plugins.xml are hard links (install() copies a symlink as a symlink), and
# $(PKG_DIR)/../shared is the repository's ../shared, so `$(find clod_haptics)/../shared` still resolves.
# Refreshed on every call (new entries linked, removed ones dropped); $(1) is the workspace.
PKG_DIR := $(BUILD)/pkg/clod_haptics
define link_package
	@mkdir -p $(1)/src $(PKG_DIR) $(ROS_HOME)
	@cd $(PKG_DIR) && find . -maxdepth 1 -xtype l -delete && \
	  for f in $(ROOT)/* $(ROOT)/.[!.]*; do \
	    n=$${f##*/}; case $$n in .build|.git|'.[!.]*') continue;; package.xml|nodelet_plugins.xml) \
	      [ $$n -ef $$f ] || ln -f $$f $$n; continue;; esac; \
	    [ "$$(readlink $$n)" = "$$f" ] || ln -sfn $$f $$n; \
	  done && ln -sfn $(abspath $(ROOT)/../shared) $(BUILD)/pkg/shared
	@[ "$$(readlink $(1)/src/clod_haptics)" = "$(PKG_DIR)" ] || { rm -rf $(1)/src/clod_haptics; ln -sfn $(PKG_DIR) $(1)/src/clod_haptics; }
endef

.PHONY: link-package
link-package:
	$(call link_package,$(WS))

build: deps link-package
	@$(CATKIN) all $(if $(INSTALL_ON),install)

# The install space is refreshed first: test/package/test_install_space.py builds test/downstream against it.
test: deps link-package
	@$(CATKIN) all tests install | grep -v -E '^-- (Installing|Up-to-date|Set runtime path)'; exit $${PIPESTATUS[0]}
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
	@echo "== clod_haptics demo ($(SPACE)): bundled stylus bag -> bag_replay -> detector over $(DEMO_MESH) (log: $(BUILD)/demo.log) =="
	@port=$${DEMO_PORT:-$$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')} && \
	  $(SETUP) && export ROS_MASTER_URI=http://localhost:$$port CLOD_BAG_WAIT_FOR_SUBSCRIBERS=2 && \
	  timeout -k 10 180 python3 $(CONTACT_SUMMARY) --timeout 150 --log $(BUILD)/demo.log -- \
	  roslaunch -p $$port clod_haptics clod_haptics.launch device:=bag rviz:=false

# The core alone, no ROS master: a CLOD sweep of the bundled mesh.
demo-core: build
	@echo "== clod_haptics core demo: CLOD sweep of the bundled mesh ($(DEMO_MESH)) =="
	@$(TOOL) sweep --mesh $(DEMO_MESH) --normalize --distances 0,0.01,0.02,0.03,0.04,0.05,0.06,0.07,0.08

# RViz under a virtual X server (xvfb-run), the pipeline on MESH (default the bundled torus; SCALE file units to
# metres, or SIZE=0.15 for a .off/.obj whose largest side becomes 0.15 m) with the mouse stylus (device:=marker)
# driven into it, the screen grabbed with ImageMagick's import: SHOT (default .build/screenshot.png, log beside it).
#   make screenshot MESH=../shared/data/meshes/elephant.off SIZE=0.15 SHOT=doc/screenshot_elephant.png
.PHONY: screenshot
SHOT ?= $(BUILD)/screenshot.png
screenshot: build deps-screenshot
	@$(SETUP) && $(if $(SIZE),SIZE=$(SIZE)) $(ROOT)/scripts/screenshot.sh $(abspath $(SHOT)) \
	  $(if $(MESH),$(abspath $(MESH)),$(DEMO_MESH)) $(if $(SCALE),$(SCALE),1.0)

# Soak: the shipped launch/clod_haptics.launch with its defaults under a 1 kHz pose stream for SOAK_SECONDS
# (default 600) with ~markers subscribed and a `dynparam set` process started every second (scripts/soak.py).
# Its own master on a free port; mesh ../shared mannequin-devil.off scaled to 15 cm, else the bundled torus.
# Prints poses, unanswered, manager RSS, warnings and detection-time percentiles; exit 1 on an unanswered
# pose, RSS growth beyond the bound after warm-up, or an unexpected warning. Launch log: .build/soak.log.
# Not in `make test` (test/rostest/soak_short.test runs the script for 20 s there). SOAK_ARGS: more options.
SOAK_SECONDS ?= 600
.PHONY: soak
soak: build
	@$(SETUP) && python3 $(ROOT)/scripts/soak.py --duration $(SOAK_SECONDS) --log $(BUILD)/soak.log $(SOAK_ARGS)

clean:
	rm -rf $(BUILD)

# ---------------------------------------------------------------------------------------------
# Fuzzing and sanitizers.
# `make fuzz` builds the libFuzzer targets in fuzz/ with clang-14 (-fsanitize=fuzzer,address,undefined)
# against the core sources and runs each for FUZZ_SECONDS (default 60); a crash leaves its input in
# .build/fuzz/artifacts and fails the target. `make test-sanitize` builds the whole suite with
# -DCLOD_SANITIZE=ON (ASan + UBSan) in its own workspace .build/ws-sanitize and runs every test.
APT_FUZZ := clang-14 libclang-rt-14-dev libeigen3-dev libassimp-dev
FUZZ_DIR := $(BUILD)/fuzz
FUZZ_SECONDS ?= 60
FUZZ_CXX := clang++-14
FUZZ_CXXFLAGS := -std=c++17 -g -O1 -fno-omit-frame-pointer -fno-sanitize-recover=undefined \
  -I$(ROOT)/include -isystem /usr/include/eigen3
FUZZ_TARGETS := fuzz_mesh_load fuzz_query fuzz_cache_read
# Every core source, the subfolders' (simd/, mesh_readers/) included.
FUZZ_CORE_OBJS := $(patsubst $(ROOT)/src/core/%.cpp,$(FUZZ_DIR)/obj/%.o,$(wildcard $(ROOT)/src/core/*.cpp $(ROOT)/src/core/*/*.cpp))
SAN_WS := $(BUILD)/ws-sanitize
# Every sanitizer report of every process (test binaries, nodes, the nodelet manager with ASan preloaded) goes
# to a file of its own in SAN_REPORTS: a report at exit (a leak) or in a child whose output no one reads still
# fails the target. The workspace's env hook sets CLOD_TIME_SCALE=4 there (see CMakeLists.txt).
SAN_REPORTS := $(BUILD)/sanitize_reports
SAN_ENV := ASAN_OPTIONS=detect_leaks=1:halt_on_error=1:abort_on_error=0:log_path=$(SAN_REPORTS)/asan \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:log_path=$(SAN_REPORTS)/ubsan \
  LSAN_OPTIONS=suppressions=$(ROOT)/fuzz/lsan.supp:print_suppressions=0

.PHONY: deps-fuzz fuzz-build fuzz test-sanitize
.SECONDARY: $(FUZZ_CORE_OBJS)

deps-fuzz:
	$(call apt_install,$(APT_FUZZ))

$(FUZZ_DIR)/obj/%.o: $(ROOT)/src/core/%.cpp $(wildcard $(ROOT)/include/clod_haptics/core/*.h $(ROOT)/src/core/*.h $(ROOT)/src/core/*/*.h)
	@mkdir -p $(@D)
	@$(FUZZ_CXX) $(FUZZ_CXXFLAGS) -fsanitize=fuzzer-no-link,address,undefined -c $< -o $@

$(FUZZ_DIR)/%: $(ROOT)/fuzz/%.cpp $(ROOT)/fuzz/fuzz_common.h $(FUZZ_CORE_OBJS)
	@echo "== building $@"
	@$(FUZZ_CXX) $(FUZZ_CXXFLAGS) -fsanitize=fuzzer,address,undefined $< $(FUZZ_CORE_OBJS) -lassimp -lpthread -o $@

fuzz-build: deps-fuzz
	@$(MAKE) --no-print-directory $(addprefix $(FUZZ_DIR)/,$(FUZZ_TARGETS))

# Seeds: the test fixtures behind a selector byte (0 .off, 1 .obj, 2 .stl, 3 .ply; bit 2 normalises); for
# fuzz_cache_read one byte per cache file (0 mesh, 1 sphere set, 2 grid: the file as written, no edits); plus
# fuzz/regressions/<target>/ (inputs that once failed; each also has a gtest).
fuzz: fuzz-build
	@mkdir -p $(FUZZ_DIR)/artifacts $(addprefix $(FUZZ_DIR)/corpus/,$(FUZZ_TARGETS)) \
	  $(addprefix $(ROOT)/fuzz/regressions/,$(FUZZ_TARGETS))
	@for k in 0 1 2; do printf "\\x0$$k" > $(FUZZ_DIR)/corpus/fuzz_cache_read/seed_file_$$k; done
	@s=$(FUZZ_DIR)/corpus/fuzz_mesh_load; d=$(ROOT)/test/data; \
	  for f in cube.off:04 cube.obj:05 cube_quads.obj:01 cube_ascii.stl:06 cube_binary.stl:02 cube_ascii.ply:07 \
	           cube_binary.ply:03 cube_with_zero_area.obj:15 nonconvex_polygons.obj:01 cube.dae:04; do \
	    n=$${f%%:*}; printf "\\x$${f#*:}" > $$s/seed_$$n; cat $$d/$$n >> $$s/seed_$$n; done; \
	  printf '\x00' > $$s/seed_degtri_sliding.off; cat $(SHARED_DIR)/data/meshes/degtri_sliding.off >> $$s/seed_degtri_sliding.off 2>/dev/null; true
	@status=0; for t in $(FUZZ_TARGETS); do \
	  echo "== $$t for $(FUZZ_SECONDS) s (log: $(FUZZ_DIR)/$$t.log)"; \
	  (cd $(FUZZ_DIR) && LSAN_OPTIONS=suppressions=$(ROOT)/fuzz/lsan.supp ./$$t corpus/$$t $(ROOT)/fuzz/regressions/$$t -max_total_time=$(FUZZ_SECONDS) -timeout=30 -rss_limit_mb=4096 \
	    $$([ $$t = fuzz_cache_read ] && echo -max_len=121 -len_control=0) \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/$$t- -print_final_stats=1 > $$t.log 2>&1); rc=$$?; \
	  grep -E '^(stat::number_of_executed_units|stat::peak_rss_mb)|^#[0-9]+ +DONE' $(FUZZ_DIR)/$$t.log | tr '\n' ' '; echo; \
	  if [ $$rc -ne 0 ]; then status=1; echo "$$t FAILED (exit $$rc):"; grep -E 'ERROR|invariant|runtime error|SUMMARY|Test unit written' $(FUZZ_DIR)/$$t.log | head -10; fi; \
	done; exit $$status

# The last line is count_test_results.py's `N passed, N failed` over the sanitizer workspace; the target exits
# non-zero when a case failed, a test produced no result, or any process wrote a sanitizer report.
test-sanitize: deps
	@mkdir -p $(BUILD)/ros_home-sanitize
	$(call link_package,$(SAN_WS))
	@echo "== building the suite with ASan+UBSan in $(SAN_WS) (log: $(BUILD)/sanitize_build.log)"
	@t0=$$(date +%s); cd $(SAN_WS) && catkin_make -j$(JOBS) --cmake-args -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCLOD_SANITIZE=ON \
	  $(CMAKE_EXTRA) --make-args all tests > $(BUILD)/sanitize_build.log 2>&1 || { tail -30 $(BUILD)/sanitize_build.log; exit 1; }; \
	  echo "== build: $$(( ($$(date +%s) - t0) / 60 )) min $$(( ($$(date +%s) - t0) % 60 )) s"
	@rm -rf $(SAN_WS)/build/test_results $(SAN_REPORTS) && mkdir -p $(SAN_REPORTS)
	@echo "== running every test under the sanitizers (log: $(BUILD)/sanitize_run_tests.log, reports: $(SAN_REPORTS))"
	@t0=$$(date +%s); source $(SAN_WS)/devel/setup.bash && cd $(SAN_WS) && export ROS_HOME=$(BUILD)/ros_home-sanitize \
	  ROS_LOG_DIR=$(BUILD)/ros_home-sanitize/log $(SAN_ENV) && catkin_make -j1 run_tests > $(BUILD)/sanitize_run_tests.log 2>&1; \
	  echo "== tests: $$(( ($$(date +%s) - t0) / 60 )) min $$(( ($$(date +%s) - t0) % 60 )) s (CLOD_TIME_SCALE=$$CLOD_TIME_SCALE)"; \
	  grep -E '^\[ +(FAILED|SKIPPED) +\]|\]\[FAILURE\]|FAILURES: [1-9]|ERROR: max time|runtime error|Sanitizer|ASan runtime' \
	    $(BUILD)/sanitize_run_tests.log | tail -40 || true
	@source $(SAN_WS)/devel/setup.bash; status=0; \
	  if grep -qE 'runtime error:|ERROR: (Address|Leak|UndefinedBehavior)Sanitizer|ASan runtime does not come first' \
	      $(BUILD)/sanitize_run_tests.log; then status=1; echo "sanitizer messages in $(BUILD)/sanitize_run_tests.log"; fi; \
	  for f in $$(ls $(SAN_REPORTS)); do status=1; echo "== sanitizer report $(SAN_REPORTS)/$$f:"; \
	    grep -E 'ERROR|SUMMARY|runtime error|^    #[0-9]+ ' $(SAN_REPORTS)/$$f | head -25; done; \
	  python3 $(ROOT)/scripts/count_test_results.py $(SAN_WS)/build/test_results || status=1; exit $$status
