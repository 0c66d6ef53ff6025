"""The test suite mirrors the package: tests/encoder, tests/render, tests/format, ... (see
tests/README.md). This file's folder is on sys.path for every test, so shared helpers such as
kernel_inputs.py are imported by name."""
