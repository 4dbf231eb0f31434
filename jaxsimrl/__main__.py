from jaxsimrl.cli.main import entry

entry()
