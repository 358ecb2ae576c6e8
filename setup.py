"""The compiled parts: the tokenizer of diagnostic records, and the reduction of records to activity runs.

Both are optional: without a C compiler the package installs without them, and parsers.diag.read and
console.analysis.passages.buckets use their numpy paths, which give the same results (tests check both)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("parsers.diag.compiled_tokens", ["parsers/diag/compiled_tokens.c"], optional=True),
        Extension(
            "console.analysis.passages.compiled_runs",
            ["console/analysis/passages/compiled_runs.c"],
            optional=True,
        ),
        Extension(
            "console.analysis.counting.compiled_pairs", ["console/analysis/counting/compiled_pairs.c"], optional=True
        ),
        Extension(
            "console.analysis.passages.compiled_json",
            ["console/analysis/passages/compiled_json.c"],
            optional=True,
        ),
    ]
)
