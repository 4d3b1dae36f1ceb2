"""Living as one long-running process: child processes that die with it, log storms throttled, ast.parse
serialised across threads (Python 3.11)."""
