"""The compiled tokenizer of diagnostic records (optional: without a C compiler the package installs without it,
and parsers.diag.read uses its numpy tokenizer, which gives the same result)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("parsers.diag._tokenize_c", ["parsers/diag/_tokenize_c.c"], optional=True),
    ]
)
