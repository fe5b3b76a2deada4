"""Stand-in: the LBF anchor runs no PAC-DCG."""


def scatter_add(*args, **kwargs):
    raise RuntimeError("torch_scatter stand-in: not for PAC-DCG")
