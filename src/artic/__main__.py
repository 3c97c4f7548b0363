"""`python -m artic` is the same as the `artic` console script."""

from artic.cli.main import main

if __name__ == "__main__":
    main()
