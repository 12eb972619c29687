"""Code for a probe process (``exec`` it there): ``found`` lists the kernels numba compiles in the calling thread
from then on (numba's compile events, by thread). Shared by the tests that check a step compiles nothing in the
caller's thread."""

LISTENER = """
import threading
from numba.core import event
main, found = threading.get_ident(), []

class Listener(event.Listener):
    def on_start(self, ev):
        if threading.get_ident() == main:
            found.append(ev.data["dispatcher"].py_func.__qualname__)

    def on_end(self, ev):
        pass

event.register("numba:compile", Listener())
"""
