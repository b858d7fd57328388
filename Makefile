# The two commands a new user runs (README): `make run` and `make test`.
# Both do the whole set-up first (scripts/setup.sh: Debian packages, npm data).
BUILD       ?= build
BUILD_ASAN  ?= build-asan
JOBS        ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all run test test-fast test-quick asan tsan fuzz soak setup build clean

all: build

setup:
	@scripts/setup.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo $(CMAKE_FLAGS) >/dev/null

build: setup $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS) -- --no-print-directory

# Renders the procedural demo scene (no download needed) to out/demo.png.
run: build
	@mkdir -p out
	./$(BUILD)/lucent render scenes/demo.json --method reference -o out/demo.png
	@echo "wrote out/demo.png"

# The whole suite: the optimised build, then the same suite under ASan+UBSan.
test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)
	$(MAKE) --no-print-directory asan

test-fast: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The tests labelled fast (CMakeLists.txt: every test is fast or slow, and gpu
# when it needs a GPU context).
test-quick: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L fast

# intercept_tls_get_addr=0: GCC 12's LeakSanitizer misreads glibc >= 2.25's
# dynamic TLS blocks (libLLVM's, via llvmpipe) and can crash its tracer at exit;
# evidence and why no leak coverage is lost: tests/cli/lib.sh, docs/gpu.md.
asan: setup
	cmake -S . -B $(BUILD_ASAN) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLUCENT_SANITIZE=ON $(CMAKE_FLAGS) >/dev/null
	cmake --build $(BUILD_ASAN) -j $(JOBS) -- --no-print-directory
	cd $(BUILD_ASAN) && ASAN_OPTIONS=detect_leaks=1:intercept_tls_get_addr=0 UBSAN_OPTIONS=print_stacktrace=1 LUCENT_ASAN=1 \
	  ctest --output-on-failure -j $(JOBS)

# Every libFuzzer target for FUZZ_SECONDS seconds (default 60), or FUZZ_RUNS
# executions if that comes first, from the committed corpus; installs clang
# and its fuzzer runtime first.
FUZZ_SECONDS ?= 60
FUZZ_RUNS ?= -1
fuzz: setup
	FUZZ_SECONDS=$(FUZZ_SECONDS) FUZZ_RUNS=$(FUZZ_RUNS) scripts/fuzz.sh

# Two renderers at once, and the worker pool, under ThreadSanitizer.
# tests/tsan.supp lists the races it reports inside Mesa's llvmpipe, which
# lucent does not own.
BUILD_TSAN ?= build-tsan
tsan: setup
	cmake -S . -B $(BUILD_TSAN) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLUCENT_TSAN=ON $(CMAKE_FLAGS) >/dev/null
	cmake --build $(BUILD_TSAN) -j $(JOBS) --target test_concurrency test_parallel -- --no-print-directory
	cd $(BUILD_TSAN) && TSAN_OPTIONS="halt_on_error=1 suppressions=$(CURDIR)/tests/tsan.supp" \
	  ctest --output-on-failure -R '^test_(concurrency|parallel)$$'

# The long runs kept out of the suite (about 30 minutes): the full
# allocation-failure sweep, 1000 library frames per method, 2000 scripted
# viewer frames under Xvfb, and their memory plot (scripts/soak.sh).
soak: build
	scripts/soak.sh $(BUILD)

clean:
	rm -rf $(BUILD) $(BUILD_ASAN) $(BUILD_TSAN) out
