import pytest


@pytest.fixture
def cli_main(monkeypatch):
    """aerial_synth.cli.main with only the vehicles commands registered, so these tests do
    not depend on the other packages' CLI modules being present."""
    import aerial_synth.cli as cli

    monkeypatch.setattr(cli, "COMMANDS", {k: v for k, v in cli.COMMANDS.items() if v[0] == "aerial_synth.vehicles.cli"})
    return cli.main
