"""Files: scenario files (TOML) in and out, and saved runs (``jaxarm solve --json``).

The only layer that reads or writes files for the library; the CLI and the report use it.
"""
