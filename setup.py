"""The compiled tokenizer of diagnostic records (optional: without a C compiler the package installs without it,
and parsers.diag.read uses its numpy tokenizer, which gives the same result)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("parsers.diag.compiled_tokens", ["parsers/diag/compiled_tokens.c"], optional=True),
    ]
)
