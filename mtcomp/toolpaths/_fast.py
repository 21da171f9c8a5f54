"""Fast path placeholder."""


def available() -> bool:
    return False
