# Only the cffi hook lives here: cffi's setuptools plugin builds canopenfd._core
# from build_ext.py. Everything else is in pyproject.toml.
from setuptools import setup

setup(cffi_modules=["build_ext.py:ffibuilder"])
