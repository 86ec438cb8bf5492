"""Allow ``python -m scftc_cli``."""

from scftc_cli.commands.app import main

if __name__ == "__main__":
    main()
