"""The command line (``cli``: ``mrlib train``, ``sample``, ``restyle``, ...) and the
end-to-end demo (``demo``)."""
