"""numba's on-disk cache of the kernels, keyed on every source of :mod:`reduced.kernels`.

numba keys a function's cache on its own file's modification time and size, but a kernel
compiled in one file carries the code it calls from the others (numba links callees into the
caller): after an edit of physics.py a cached driver of partition.py would still run the old
physics. :func:`follow_the_whole_package`, called by the package before any kernel is defined,
stamps every kernel's cache with the hash of all the package's sources instead.
"""

from __future__ import annotations


def follow_the_whole_package() -> None:
    """Put locators before numba's own for the files of this package, with the package's
    stamp. Uses numba internals (numba.core.caching); if they change, numba's default applies
    (seen otherwise: edit physics.py, and a cached driver still returns the old result)."""
    import glob
    import hashlib
    import os

    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover
        return
    root = os.path.dirname(os.path.abspath(__file__))

    digest = hashlib.sha256()
    for path in sorted(glob.glob(os.path.join(root, "**", "*.py"), recursive=True)):
        with open(path, "rb") as f:
            digest.update(os.path.relpath(path, root).encode() + b"\0" + f.read())
    stamp = digest.digest()  # the sources do not change while the process runs

    class _PackageStamp:
        def get_source_stamp(self):
            return stamp

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.abspath(py_file).startswith(root + os.sep):
                return None
            return super().from_function(py_func, py_file)

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    bases = [getattr(caching, name, None) for name in
             ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    if impl is None or None in bases or not isinstance(getattr(impl, "_locator_classes", None), list):
        return  # pragma: no cover
    if any(getattr(c, "_xval_kernels", False) for c in impl._locator_classes):
        return
    ours = [type("Kernels" + b.__name__, (_PackageStamp, b), {"_xval_kernels": True}) for b in bases]
    impl._locator_classes[:0] = ours
