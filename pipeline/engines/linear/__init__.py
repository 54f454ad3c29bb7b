"""The linearised whisker chain as an engine-neutral simulator (:mod:`.chain`: its matrices,
:mod:`.modal`: their exact integration, :mod:`.motion`: base motions as its inputs,
:mod:`.wrench`: the base wrench, :mod:`.free`: the free-whisker path of the engines)."""
