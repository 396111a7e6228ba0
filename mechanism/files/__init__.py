"""Files: atomic outputs, CSV tables with units, plots, bounded untrusted input, captured stderr,
the checked cache, interrupts."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "outputs": ("atomic_file", "atomic_path", "atomic_dir", "transaction", "check_outputs"),
        "tables": ("read_table", "write_table", "parse_table", "check_increasing", "true_runs"),
        "limits": ("number", "check_number", "read_bounded", "check_elements"),
        "capture": ("captured_stderr", "captured_stdout", "LineTracker"),
        "plotting": ("plt", "save_figure"),
        "cache": ("cache_info", "clear_cache", "cache_root"),
        "interrupts": ("Interrupted",),
    },
)
