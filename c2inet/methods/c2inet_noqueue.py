"""The queue-free control: C2INet's network with a fixed N(0, I) prior on C and no regulariser.

Everything but the queue is C2INet's (architecture, losses, the three test-time rules for C, whose
prior is here N(0, I)), so the difference between the two measures what the queue itself
contributes, under each rule.
No hooks. Example: ``--methods c2inet-online,c2inet-noqueue``
"""

import torch

from c2inet.methods.base import Method
from c2inet.model import C2INetModel
from c2inet.model_config import C2INET_SPACE


class C2INetNoQueue(Method):
    """C2INet's model with the prior queue held at N(0, I): the control for the queue."""

    name = "c2inet-noqueue"
    search_space = C2INET_SPACE

    def build_model(self) -> torch.nn.Module:
        return C2INetModel(self.model_config)
