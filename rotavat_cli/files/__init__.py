"""Files rotavat writes: atomically (a temporary file, then a rename), never over what it did not write, and YAML
with its header.

Modules (docs/architecture.md):

- :mod:`.atomic`: atomic files and staged folders;
- :mod:`.outputs`: what rotavat wrote (its marker and headers): never replacing anything else;
- :mod:`.yaml_io`: YAML read with `yaml.safe_load`, written atomically with rotavat's header.
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".atomic": ("atomic_open", "atomic_path", "atomic_write_text", "staged_directory"),
    ".outputs": (
        "MARKER", "TEXT_HEADER", "STAGING_OWNER", "TEMP_TAG", "check_output_dir", "check_output_file",
        "mark_output_dir", "is_rotavat_dir", "written_by_rotavat", "remove_stale_staging", "own_staging",
        "own_temporary", "release", "in_own_staging", "beside", "imported_output", "as_typed", "RRD_APPLICATION_ID"
    ),
    ".yaml_io": ("read_yaml", "write_yaml"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
