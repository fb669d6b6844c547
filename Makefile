# Thin wrapper around CMake. The package list lives in tools/debian-packages.txt.
BUILD      ?= build
JOBS       ?= $(shell nproc 2>/dev/null || echo 2)
PACKAGES   := $(shell grep -v '^\#' tools/debian-packages.txt)
SUDO       := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: all deps build demo test bench fuzz format clean

all: build

# A package counts as present when installed or provided by an installed one (e.g. NodeSource's
# nodejs provides npm). The live view's npm packages (web/package-lock.json) follow.
deps:
	@provided=$$(dpkg-query -W -f='$${Status}|$${Provides}\n' 2>/dev/null | grep '^install ok installed|' \
	  | cut -d'|' -f2 | tr ',' '\n' | sed 's/(.*//; s/ //g'); \
	missing=""; for p in $(PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "ok installed" || \
	  echo "$$provided" | grep -qx "$$p" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "make deps: installing$$missing"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing; \
	fi
	@if [ ! -d web/node_modules ]; then \
	  echo "make deps: npm ci in web/ (uPlot for rths view, puppeteer-core for its browser test)"; \
	  cd web && npm ci --no-audit --no-fund; \
	fi

build: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	./tools/demo.sh $(BUILD)/rths out/demo

# From scratch: a -Werror build with the whole suite, then the ASan+UBSan build of the suite less
# the tests labelled long (CMakeLists.txt: whole sweeps, campaigns, browsers; minutes each).
test: deps
	rm -rf build-test build-asan
	cmake -S . -B build-test -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRTHS_WERROR=ON
	cmake --build build-test -j $(JOBS)
	cd build-test && ctest --output-on-failure -j $(JOBS)
	cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DRTHS_WERROR=ON -DRTHS_SANITIZE=ON
	cmake --build build-asan -j $(JOBS)
	cd build-asan && ctest --output-on-failure -j $(JOBS) -LE long

bench: build
	cmake --build $(BUILD) -j $(JOBS) --target rths_bench
	$(BUILD)/rths_bench

# libFuzzer (clang), bounded in time, on the controller link's frame decoder and on the
# configuration reader (inputs up to 64 KiB, 10 s each: a hang is a finding; the reader bounds
# nesting itself). New inputs go to build-fuzz/corpus*, findings to build-fuzz/; the checked-in
# seeds (fuzz/corpus, examples, tests/data/bad_configs) are only read.
FUZZ_SECONDS ?= 60
FUZZ_FLAGS := -std=c11 -D_GNU_SOURCE -g -O1 -Iinclude -fsanitize=fuzzer,address,undefined \
  -fno-sanitize-recover=all
fuzz: deps
	mkdir -p build-fuzz/corpus build-fuzz/corpus_config
	clang $(FUZZ_FLAGS) fuzz/fuzz_frame.c src/controller/protocol.c -lm -o build-fuzz/fuzz_frame
	build-fuzz/fuzz_frame -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 build-fuzz/corpus fuzz/corpus
	clang $(FUZZ_FLAGS) fuzz/fuzz_config.c src/core/config.c src/core/linalg.c \
	  $$(pkg-config --cflags --libs libfyaml lapacke openblas) -lm -o build-fuzz/fuzz_config
	build-fuzz/fuzz_config -max_total_time=$(FUZZ_SECONDS) -max_len=65536 -timeout=10 \
	  -artifact_prefix=build-fuzz/ -print_final_stats=1 build-fuzz/corpus_config examples \
	  tests/data/bad_configs

format:
	clang-format -i $$(git ls-files '*.c' '*.h')

clean:
	rm -rf build build-test build-asan build-fuzz out
