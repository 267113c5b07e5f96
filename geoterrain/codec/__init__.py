"""The height codec: the quantizer and its choice, the prediction U(.), the entropy
coder and the residual pyramid codec.
"""

__all__ = ["entropy", "predict", "pyramid", "quantchoice", "quantize"]
