"""Restricted readers of untrusted files: numpy arrays, numpy scalars and builtin containers only
(``collections.defaultdict`` too, with a builtin type as its factory).

HPS demos save results as pickles (plain ``pickle``, ``joblib.dump``, or object arrays inside
``np.savez``). Unpickling runs whatever callable the file names, so a hostile file can execute
code. This package never hands user data to the standard unpickler (nor lets numpy unpickle):
every global a pickle asks for is looked up in an explicit allow-list (``allowed.ALLOWED``), and
each allowed callable is a wrapper that checks its arguments before building anything. Anything
else (``os.system``, ``builtins.eval``, ``torch``, ``pandas``, ``numpy.ma`` ...) raises an
:class:`~rotavat_cli.errors.InputError` whose one-line message names the file and the refused global.

One concern per module, each built on the ones before it (no module imports one after it):

- ``refusal``: ``Refused`` and :func:`unpickling_errors`, which turns it (and every way
  broken bytes fail) into a one-line error naming the file;
- ``checks``: sizes checked before allocating (arrays, the ``Budget`` of one pickle);
  ``expansion``: the items shared references add when converted; ``dtypes``: a pickled dtype's
  state rebuilt by numpy's constructor, never handed to numpy as it stands;
- ``allowed``: the allow-list and its checked builders; ``streams``: files within
  ``max_file_mb``, streams read a chunk at a time, compressed streams inflated as they are read;
- ``core``: the restricted unpickler (allow-list, budget, joblib's array placeholders);
- ``torch_tensors``: torch's tensor globals as inert numpy builders; ``torch_files``: the
  unpickler with them (``TensorUnpickler``) and ``torch.save`` archives and legacy streams;
- ``pickles``: plain and joblib pickles (any compression); ``npy``, ``npz``: numpy files, object
  arrays through ``pickles``; ``dispatch``: :func:`load_file`, a torch file or a pickle;
- ``model_files``: the official SMPL-family ``.pkl`` model files, their chumpy arrays and scipy
  sparse matrices rebuilt as numpy arrays from their state (:func:`load_model_pickle`).

Sizes are checked before anything is allocated, against :mod:`rotavat_cli.settings.limits` (the config's
``limits:`` section): files and decompressed streams (``max_file_mb``), every array a header or a
pickle declares (``max_array_mb``), the objects a pickle builds and the items its shared
references add when expanded (``max_pickle_items``). A compressed pickle (joblib's, an ``.npz``
member, a torch archive's ``data.pkl``) is unpickled as it inflates, never inflated whole first: a
decompression bomb is refused at its first byte that is not a pickle's, or once ``max_file_mb`` came
out, holding one chunk; a compressed file costs what the objects it holds cost, as an uncompressed
one does.

>>> import pickle
>>> from rotavat_cli.unpickle import loads
>>> loads(pickle.dumps({"a": [1, 2.5]}), "demo.pkl")
{'a': [1, 2.5]}
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".dispatch": ("load_file",),
    ".model_files": ("load_model_pickle", "loads_model"),
    ".npy": ("load_npy", "load_npy_bytes"),
    ".npz": ("NpzArchive", "load_npz", "open_npz"),
    ".pickles": ("loads",),
    ".refusal": ("unpickling_errors",),
    ".torch_files": ("MAGIC_NUMBER", "is_legacy_torch", "is_torch_zip", "load_torch", "load_torch_bytes"),
    ".torch_tensors": ("TORCH_GLOBALS",),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
