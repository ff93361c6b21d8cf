"""A cache for kernel factories that gives one kernel per set of argument values however they are
passed: ``f(a)``, ``f(a, True)`` and ``f(a, flag=True)`` (``flag`` defaulting to True) are one cache
entry, where ``functools.cache`` would build (and compile) the same kernel three times."""

import functools
import inspect


def kernel_factory(factory):
    """``factory`` cached on its arguments bound to its signature, defaults applied; the result keeps
    ``cache_clear``."""
    signature = inspect.signature(factory)
    cached = functools.cache(factory)

    @functools.wraps(factory)
    def make(*args, **kwargs):
        bound = signature.bind(*args, **kwargs)
        bound.apply_defaults()
        return cached(*bound.args, **bound.kwargs)

    make.cache_clear = cached.cache_clear
    return make
