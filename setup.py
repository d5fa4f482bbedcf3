"""The one compiled part of navd, optional: without a C compiler it installs without
it and navd/filter/ekf_step.py takes every step in Python (the same arithmetic)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "navd.filter._ekf_step",
            sources=["navd/filter/_ekf_step.c"],
            # IEEE arithmetic as Python does it: no fused multiply-adds (aarch64 has them)
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        )
    ]
)
