# Thin wrapper over CMake. `make demo` and `make test` install what is missing
# (Debian packages, as root), build, and run.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all deps deps-build build demo test check-long clean abi-baseline \
        check-sanitizers check-asan check-tsan check-fuzz fuzz fuzz-build

all: build

deps:
	@bash .ci/deps.sh

deps-build:
	@bash .ci/deps.sh build

$(BUILD)/CMakeCache.txt: CMakeLists.txt
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

# The demo builds only the command line and the plugin it loads (not the tests).
demo: deps-build $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS) --target rbcloth_cli
	$(BUILD)/bin/rbcloth run --out out

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The import sweep over every file of assimp-testmodels under valgrind memcheck,
# the import helpers included (`make test` runs every 8th file; this one all of
# them, tens of minutes on 2 cores).
check-long: build
	mkdir -p $(BUILD)/tests/import/valgrind-long
	sh tests/import/valgrind_sweep.sh $(BUILD)/tests/import/valgrind-long \
	  tests/import/valgrind-assimp.supp \
	  $(BUILD)/bin/import_sweep --quiet --timeout 300 --min-imported 300 /usr/share/assimp/models

# Sanitizers and fuzzing (tests/README.md, "Sanitizers and fuzzing"), each in its own
# build folder:
#   check-asan   every test of an ASan + UBSan build (gcc), but those labelled
#                external (valgrind, Chromium, Blender, Slurm, Xvfb: see cmake/TestLabels.cmake)
#   check-tsan   the tests labelled threads in a ThreadSanitizer build (clang: gcc's TSan
#                cannot load the plugin's target_clones resolvers)
#   check-fuzz   the three libFuzzer targets of tests/fuzz for FUZZ_SECONDS each (clang,
#                ASan + UBSan); whatever they find lands in tests/fuzz/regress/
#   fuzz         one target by hand: make fuzz FUZZ_TARGET=cloth FUZZ_SECONDS=3600
#                (KEEP_GOING=1 goes on past what it finds)
#   check-sanitizers  all three (.ci/run calls it after `make test`), then their times
ASAN_BUILD ?= build-san-asan
TSAN_BUILD ?= build-san-tsan
FUZZ_BUILD ?= build-san-fuzz
SAN_CC ?= clang-14
FUZZ_SECONDS ?= 60
FUZZ_TARGET ?= cloth
ASAN_CTEST_ARGS ?= -LE external
TSAN_CTEST_ARGS ?= -L threads -LE external
SAN_DIR := $(CURDIR)/tests/sanitizers
# halt_on_error/-fno-sanitize-recover: the first report fails the test. Leaks are
# checked (detect_leaks) with one suppression, libgomp's own (tests/sanitizers/lsan.supp).
# allocator_may_return_null: an absurd malloc returns NULL as glibc's does, so the
# library's out-of-memory paths run instead of ASan aborting on the size.
ASAN_ENV := ASAN_OPTIONS=detect_leaks=1:halt_on_error=1:abort_on_error=0:allocator_may_return_null=1:strict_string_checks=1:check_initialization_order=1:detect_stack_use_after_return=1 \
  LSAN_OPTIONS=suppressions=$(SAN_DIR)/lsan.supp:print_suppressions=0 \
  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
TSAN_ENV := TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:history_size=4:suppressions=$(SAN_DIR)/tsan.supp \
  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1

check-asan: deps
	cmake -S . -B $(ASAN_BUILD) -DRBC_SANITIZE=address,undefined $(CMAKE_FLAGS)
	cmake --build $(ASAN_BUILD) -j $(JOBS)
	cd $(ASAN_BUILD) && $(ASAN_ENV) ctest --output-on-failure -j $(JOBS) $(ASAN_CTEST_ARGS)

check-tsan: deps
	cmake -S . -B $(TSAN_BUILD) -DCMAKE_C_COMPILER=$(SAN_CC) -DRBC_SANITIZE=thread $(CMAKE_FLAGS)
	cmake --build $(TSAN_BUILD) -j $(JOBS)
	cd $(TSAN_BUILD) && $(TSAN_ENV) ctest --output-on-failure -j $(JOBS) $(TSAN_CTEST_ARGS)

$(FUZZ_BUILD)/CMakeCache.txt: CMakeLists.txt
	cmake -S . -B $(FUZZ_BUILD) -DCMAKE_C_COMPILER=$(SAN_CC) -DRBC_FUZZ=ON \
	  -DRBC_SANITIZE=address,undefined $(CMAKE_FLAGS)

fuzz-build: deps $(FUZZ_BUILD)/CMakeCache.txt
	cmake --build $(FUZZ_BUILD) -j $(JOBS) --target fuzz_targets

check-fuzz: fuzz-build
	@status=0; for t in scene cloth import; do \
	  bash tests/fuzz/run_fuzz.sh $(FUZZ_BUILD) $$t $(FUZZ_SECONDS) || status=1; \
	done; exit $$status

fuzz: fuzz-build
	bash tests/fuzz/run_fuzz.sh $(FUZZ_BUILD) $(FUZZ_TARGET) $(FUZZ_SECONDS)

# All three, each run even if one before it failed; the wall time of each at the end.
check-sanitizers:
	@status=0; summary=""; for c in check-asan check-tsan check-fuzz; do \
	  t0=$$(date +%s); \
	  if $(MAKE) --no-print-directory $$c; then r=ok; else r=FAILED; status=1; fi; \
	  summary="$$summary  $$c: $$r, $$(( $$(date +%s) - t0 )) s\n"; \
	done; printf "check-sanitizers:\n$$summary"; exit $$status

# Regenerate the committed ABI baseline after a deliberate ABI change.
abi-baseline: build
	abidw --no-corpus-path --exported-interfaces-only --headers-dir abi --out-file abi/rbcloth.abi $(BUILD)/lib/librbcloth.so

clean:
	rm -rf $(BUILD) out $(ASAN_BUILD) $(TSAN_BUILD) $(FUZZ_BUILD)
