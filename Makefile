# Thin wrapper over CMake. `make demo` and `make test` install what is missing
# (Debian packages, as root), build, and run.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all deps deps-build build demo test check-long clean abi-baseline

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

# The import sweep over every file of assimp-testmodels under valgrind memcheck
# (`make test` runs every 8th file; this one all of them, about 17 minutes on 2 cores).
check-long: build
	valgrind --quiet --tool=memcheck --leak-check=full --error-exitcode=99 \
	  --log-file=$(BUILD)/tests/import/valgrind-long.%p.log \
	  $(BUILD)/bin/import_sweep --quiet --timeout 300 /usr/share/assimp/models

# Regenerate the committed ABI baseline after a deliberate ABI change.
abi-baseline: build
	abidw --no-corpus-path --exported-interfaces-only --headers-dir abi --out-file abi/rbcloth.abi $(BUILD)/lib/librbcloth.so

clean:
	rm -rf $(BUILD) out
