"""ftdrake's tests, laid out like the package: ``tests/<package>/`` holds the tests of
``ftdrake.<package>`` (``tests/datasets/`` those of ``ftdrake.data``, since ``tests/data/``
holds the test data files), ``tests/project/`` those of the repository as a whole (docs,
examples, the wheel, the import layers, a new user's path), and this folder those of
ftdrake's top-level modules. Shared helpers: ``tests/helpers.py``; shared fixtures:
``tests/conftest.py``."""
