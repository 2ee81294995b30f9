"""What a run may do: the packaged defaults and a user's config file, each option's bounds, and the size limits
every reader obeys.

Modules (docs/architecture.md):

- :mod:`.config`: the packaged defaults and a user's config file: loaded and merged, nothing more;
- :mod:`.option_rules`: an option's bounds and names (`Rule`), checked once for Python and the CLI;
- :mod:`.limits`: the size limits every reader obeys (the config's `limits:` section).
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    ".config": ("DEFAULT_CONFIG_PATH", "default_config", "load_config", "merge_config", "packaged_default"),
    ".option_rules": ("Rule", "check_fields", "check_rules", "is_number", "short_repr"),
    ".limits": ("Limits", "current", "configure", "applied", "human_bytes"),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
