"""`view(env, policy)`: run a policy in the interactive viewer (filled in below)."""


def view(*a, **k):
    raise NotImplementedError
