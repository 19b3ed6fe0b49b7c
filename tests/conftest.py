import pytest

from bouncingball.physics import Ball


@pytest.fixture
def article_ball() -> Ball:
    return Ball()
