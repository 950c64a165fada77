# One entry point for humans and CI: `make demo` and `make test` are the README's two commands.
SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
CARGO_PROFILE ?= ci
# The glibc policy of `make wheel`: manylinux_2_17 (manylinux2014) installs on glibc >= 2.17
# (RHEL/CentOS 7 and later, Debian 8+, Ubuntu 14.04+).
WHEEL_POLICY ?= manylinux_2_17

.PHONY: all venv build cli demo test rust-test lint stubtest py-test wheel wheel-test clean

all: test

$(VENV)/.deps: requirements-dev.txt bench/requirements.txt
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements-dev.txt -r bench/requirements.txt
	touch $@

venv: $(VENV)/.deps

## Build the Python extension into .venv (once per run).
build: venv
	VIRTUAL_ENV=$(abspath $(VENV)) PATH=$(abspath $(VENV))/bin:$$PATH \
	  $(VENV)/bin/maturin develop -q --profile $(CARGO_PROFILE)

## The standalone binary.
cli:
	cargo build --profile $(CARGO_PROFILE) --features cli --bin foldmatch

## Fit the built-in generated demo case and print before/after figures.
demo: cli
	./target/$(CARGO_PROFILE)/foldmatch demo -o demo-out

lint: venv
	cargo fmt --all -- --check
	cargo clippy --all-targets --features python,cli -- -D warnings
	RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --features python,cli --profile $(CARGO_PROFILE)
	$(VENV)/bin/ruff check python tests $(wildcard bench)
	$(VENV)/bin/ruff format --check python tests $(wildcard bench)

## The trimesh cross-checks of the mesh I/O run with the venv's Python.
rust-test: venv
	FOLDMATCH_PYTHON=$(abspath $(PY)) cargo test --profile $(CARGO_PROFILE) --features cli

## Type stubs must match the built module.
stubtest: build
	$(PY) -m mypy.stubtest foldmatch_rs._foldmatch_rs foldmatch_rs.params

py-test: build
	$(PY) -m pytest -q tests

## A wheel for `pip install dist/foldmatch_rs-*.whl` on machines without Rust: abi3 (one wheel for
## CPython >= 3.9), release profile, linked by zig (the `ziglang` package) against glibc
## $(WHEEL_POLICY)'s symbols, so it installs on Linux older than the machine that built it.
wheel: venv
	rm -f dist/foldmatch_rs-*.whl
	VIRTUAL_ENV=$(abspath $(VENV)) PATH=$(abspath $(VENV))/bin:$$PATH \
	  $(VENV)/bin/maturin build --release --locked --zig --compatibility $(WHEEL_POLICY) -o dist

## Install that wheel into a fresh venv with no Rust on PATH; fit and run the CLI from it.
wheel-test: wheel
	$(PY) tests/wheel_smoke.py --platform $(WHEEL_POLICY) dist/foldmatch_rs-*.whl

## Everything CI runs.
test: lint rust-test stubtest py-test wheel-test

clean:
	rm -rf $(VENV) target demo-out dist
