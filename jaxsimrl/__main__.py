import sys

from jaxsimrl.cli.main import main

sys.exit(main())
