"""Is numba about to compile? A look into its on-disk cache before the first call.

numba compiles a ``cache=True`` kernel the first time a process calls it unless its cache
(``NUMBA_CACHE_DIR``, the package's ``__pycache__`` or the user cache) holds an entry for
this machine; that takes seconds to tens of seconds, once per installation. These helpers
tell beforehand, so a command can say why its first run is slow.
"""

from __future__ import annotations

import os

__all__ = ["numba_kernels", "kernel_cached", "cold_kernels", "announce_compile"]


def numba_kernels(root: str):
    """``(source file, qualname, first line)`` of every ``cache=True`` numba function under ``root``.

    Found by parsing the sources (importing them would compile them). ``first line`` is the
    function's first decorator line, which numba uses (``co_firstlineno``) in its cache names.
    """
    import ast

    def caches(keywords) -> bool:
        return any(k.arg == "cache" and isinstance(k.value, ast.Constant) and k.value.value is True
                   for k in keywords)

    def walk(node, path, prefix, options):
        for ch in ast.iter_child_nodes(node):
            if isinstance(ch, ast.FunctionDef):
                name = prefix + ch.name
                # cache=True written out, or passed as **OPTIONS with OPTIONS = dict(cache=True, ...)
                if any(isinstance(d, ast.Call) and (caches(d.keywords) or any(
                        k.arg is None and isinstance(k.value, ast.Name) and k.value.id in options for k in d.keywords))
                       for d in ch.decorator_list):
                    yield path, name, ch.decorator_list[0].lineno
                yield from walk(ch, path, name + ".<locals>.", options)
            elif isinstance(ch, ast.ClassDef):
                yield from walk(ch, path, prefix + ch.name + ".", options)

    def module(path, src):
        tree = ast.parse(src, path)
        options = {t.id for st in tree.body if isinstance(st, ast.Assign) and isinstance(st.value, ast.Call)
                   and isinstance(st.value.func, ast.Name) and st.value.func.id == "dict" and caches(st.value.keywords)
                   for t in st.targets if isinstance(t, ast.Name)}
        yield from walk(tree, path, "", options)

    if os.path.isfile(root):
        with open(root, encoding="utf-8") as fh:
            yield from module(root, fh.read())
        return
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for f in sorted(files):
            if f.endswith(".py"):
                path = os.path.join(folder, f)
                with open(path, encoding="utf-8") as fh:
                    src = fh.read()
                if "cache=True" in src:
                    yield from module(path, src)


def kernel_cached(path: str, qualname: str, line: int, magic) -> bool:
    """Does numba's cache hold a fresh compiled entry of this function for this machine?

    Uses numba's own locators (``NUMBA_CACHE_DIR``, the package's ``__pycache__``, the user
    cache), cache file names and index format, on a stand-in function with the same file,
    line and qualified name.
    """
    from numba.core.caching import CompileResultCacheImpl, IndexDataCacheFile

    ns: dict = {}
    exec(compile("\n" * (line - 1) + "def _f():\n    pass\n", path, "exec"), ns)
    func = ns["_f"]
    func.__qualname__, func.__name__ = qualname, qualname.rsplit(".", 1)[-1]
    try:
        impl = CompileResultCacheImpl(func)
    except RuntimeError:  # no writable cache location: numba cannot cache it (it compiles every run)
        return False
    loc = impl.locator
    index = IndexDataCacheFile(loc.get_cache_path(), impl.filename_base, loc.get_source_stamp())
    return any(key[1] == magic and os.path.exists(os.path.join(loc.get_cache_path(), name))
               for key, name in index._load_index().items())


def cold_kernels(*roots: str, names=None) -> tuple[int, int]:
    """How many ``cache=True`` numba kernels under ``roots`` (folders or ``.py`` files) numba's
    cache lacks for this machine: ``(to compile, all)``; ``(0, 0)`` with the JIT disabled.

    ``names``: only these kernels (the entry points Python calls: a kernel called only from
    other kernels is compiled into them and has no cache entry of its own).

    Raises
    ------
    LookupError
        No such kernels there (a wrong root).
    Exception
        Whatever numba's cache internals raise should their layout change; callers fall back.
    """
    from numba.core import config
    from numba.core.registry import cpu_target

    if config.DISABLE_JIT:
        return 0, 0
    kernels = [k for root in roots for k in numba_kernels(root) if names is None or k[1] in names]
    if not kernels:
        raise LookupError(f"no cache=True numba kernels under {', '.join(roots)}")
    magic = cpu_target.target_context.codegen().magic_tuple()
    cold = sum(not kernel_cached(path, name, line, magic) for path, name, line in kernels)
    return cold, len(kernels)


_announced: set = set()


def announce_compile(logger, what: str, seconds: float, *roots: str, names=None) -> None:
    """Log (INFO, once per process and ``what``) that numba is about to compile ``what``.

    The command line shows the line, so a first run that sits for seconds says why. Any
    failure of the cache check is silent: it is only a notice.
    """
    if what in _announced:
        return
    _announced.add(what)
    try:
        cold, total = cold_kernels(*roots, names=names)
    except Exception:
        return
    if cold:
        logger.info("first run: compiling %s with numba, once (~%d s); later runs load them from the cache",
                    what, max(1, round(seconds * cold / total)))
