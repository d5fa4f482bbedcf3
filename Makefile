# navd: the two commands are `make test` and `make demo` (see README).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: test fuzz lint demo bench-accuracy bench-sensitivity bench-replay bench-decode bench-daemon \
	bench-robustness bench-noise-check bench-attainable bench-ellipse-parts bench-ellipse-scan bench-soak bench-calibration bench-advisory bench-files bench-link-size check-armhf check-arm64 clean

$(STAMP): pyproject.toml setup.py navd/filter/_ekf_step.c navd/filter/_window.c \
		navd/filter/_buffer.h
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

# the property tests with fresh random examples, ten rounds (make test repeats one fixed set)
fuzz: $(STAMP)
	for i in 1 2 3 4 5 6 7 8 9 10; do \
	  NAVD_HYPOTHESIS=explore $(BIN)/pytest -q -p no:cacheprovider \
	    tests/test_fuzz.py tests/test_codecs.py tests/test_geodesy.py tests/test_hostile_files.py \
	    tests/test_real_receivers.py tests/test_ekf_step.py tests/test_relinearise.py || exit 1; \
	done

test: $(STAMP)
	$(BIN)/ruff check navd tests bench
	$(BIN)/mypy
	$(BIN)/pytest

lint: $(STAMP)
	$(BIN)/ruff check navd tests bench
	$(BIN)/mypy

# The daemon on the emulated vehicle (about two minutes), watched live, then reported.
demo: $(STAMP)
	$(BIN)/python -m navd.hil.demo

bench-accuracy: $(STAMP)
	$(BIN)/python -m bench.accuracy --seeds 5 --write BENCHMARKS.md

bench-sensitivity: $(STAMP)
	$(BIN)/python -m bench.sensitivity --write BENCHMARKS.md

bench-replay: $(STAMP)
	$(BIN)/python -m bench.replay_speed --write BENCHMARKS.md

# replay and export of a mutated one-hour log against the clean one (about 5 minutes)
bench-files: $(STAMP)
	$(BIN)/python -m bench.mutated_logs --write BENCHMARKS.md

bench-decode: $(STAMP)
	$(BIN)/python -m bench.decode_speed --write BENCHMARKS.md

bench-daemon: $(STAMP)
	$(BIN)/python -m bench.daemon_perf --seconds 600 --write BENCHMARKS.md

# 120 missions with drawn sensor errors and conditions (about 7 minutes on 2 cores; --jobs N)
bench-robustness: $(STAMP)
	$(BIN)/python -m bench.robustness --missions 120 --write BENCHMARKS.md

# does `navd report`'s test of the noise model (the accepted ranges' mean NIS) tell the truth?
bench-noise-check: $(STAMP)
	$(BIN)/python -m bench.noise_check --missions 120 --write BENCHMARKS.md

# the same 120 missions' truths with the bound's own noise, twice each: what an estimator
# that knows the bound's model reaches, and navd's filter on the same (about 10 minutes)
bench-attainable: $(STAMP)
	$(BIN)/python -m bench.attainable --missions 120 --draws 2 --write BENCHMARKS.md

# the same 120 missions: which part of the published ellipse (the followed belief, the
# other belief's share, the considered tide) makes it wider than the error (about 5 minutes)
bench-ellipse-parts: $(STAMP)
	$(BIN)/python -m bench.ellipse_parts --missions 120 --write BENCHMARKS.md

bench-ellipse-scan: $(STAMP)
	$(BIN)/python -m bench.ellipse_scan --missions 120 --write BENCHMARKS.md

# calibrating compass and speed from a surface circle, over 12 drawn missions (about 5 minutes)
bench-calibration: $(STAMP)
	$(BIN)/python -m bench.calibration --missions 12 --write BENCHMARKS.md

# the observability advisory on 24 drawn radial missions, flown as planned and as advised
bench-advisory: $(STAMP)
	$(BIN)/python -m bench.advisory --missions 24 --write BENCHMARKS.md

# zenoh payload sizes against a 9600-baud radio, from the log of a fresh `make demo`
bench-link-size: demo
	$(BIN)/python -m bench.link_size $$(ls -t out/demo/vehicle/log/navd-*.jsonl | head -n 1) \
	  --write BENCHMARKS.md

# an hour of the daemon under faults; needs unshare and mount (root) for the full-disk fault
bench-soak: $(STAMP)
	$(BIN)/python -m bench.soak --minutes 60 --write BENCHMARKS.md

# navd installed and run on the vehicle's 32-bit ARM computer, under qemu-user (root;
# about 15 minutes the first time, with debootstrap); check-arm64 for 64-bit ARM boards
check-armhf: $(STAMP)
	NAVD_ARCH=armhf .ci/check-armhf

check-arm64: $(STAMP)
	NAVD_ARCH=arm64 .ci/check-armhf

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache navd/filter/*.so
