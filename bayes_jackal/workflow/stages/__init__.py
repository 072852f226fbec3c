"""The stages of an analysis: each module is one stage and its typed result.

A stage is a function of the :class:`~bayes_jackal.workflow.RunContext`
and the results of the stages before it; the pipeline
(:data:`bayes_jackal.workflow.PIPELINE`) imports each from its module and
runs them in order.
"""
