import sys

try:
    from .apps.cli import main
except KeyboardInterrupt:  # Ctrl-C while the modules load
    print("qogi: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
