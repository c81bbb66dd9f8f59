"""The subcommands of ``granchain`` (``granchain.cli``: the parser and the entry point):
``run`` the commands on one scene, ``infer`` the inference, ``output`` what they share."""
