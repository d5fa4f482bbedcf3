"""navd's compiled parts, optional: without a C compiler it installs without them, and
navd/filter/ekf_step.py and navd/filter/relinearise.py do the same arithmetic in Python."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "navd.filter._ekf_step",
            sources=["navd/filter/_ekf_step.c"],
            depends=["navd/filter/_buffer.h"],
            # IEEE arithmetic as Python does it: no fused multiply-adds (aarch64 has them)
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
        Extension(
            "navd.filter._window",
            sources=["navd/filter/_window.c"],
            depends=["navd/filter/_buffer.h"],
            extra_compile_args=["-ffp-contract=off"],
            optional=True,
        ),
    ]
)
