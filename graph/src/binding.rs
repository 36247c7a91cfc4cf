//! How a kernel finds its accesses in a pass instance: by the slot tokens its pass's builder
//! returned ([`ReadSlot`], [`SourcesSlot`], [`HistorySlot`], [`WriteSlot`]). A token names the
//! declaring pass and the access's index among its reads or writes (`Access::decl`), so a token
//! of another pass is refused rather than bound to whatever sits at that index.

use crate::builder::{HistorySlot, ReadSlot, SourcesSlot, WriteSlot};
use crate::error::UnboundSlot;
use crate::schedule::{Access, Origin, PassInstance};

impl PassInstance {
    /// The own-view read its pass declared as `slot`.
    pub fn read(&self, slot: ReadSlot) -> Result<&Access, UnboundSlot> {
        let found = self.reads.iter().find(|a| a.decl == slot.index() && a.origin == Origin::Own);
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(&slot))
    }

    /// The reads of every source (in the view's source order) its pass declared as `slot`;
    /// none for a view without sources.
    pub fn sources(&self, slot: SourcesSlot) -> Result<impl Iterator<Item = &Access> + '_, UnboundSlot> {
        if slot.pass() != self.pass {
            return Err(self.unbound(&slot));
        }
        Ok(self.reads.iter().filter(move |a| a.decl == slot.index() && matches!(a.origin, Origin::Source(_))))
    }

    /// Last frame's final version its pass declared as `slot`.
    pub fn history_read(&self, slot: HistorySlot) -> Result<&Access, UnboundSlot> {
        let found = self.history_reads.iter().find(|a| a.decl == slot.index());
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(&slot))
    }

    /// The write its pass declared as `slot`.
    pub fn write(&self, slot: WriteSlot) -> Result<&Access, UnboundSlot> {
        let found = self.writes.iter().find(|a| a.decl == slot.index());
        found.filter(|_| slot.pass() == self.pass).ok_or_else(|| self.unbound(&slot))
    }

    fn unbound(&self, slot: &impl std::fmt::Debug) -> UnboundSlot {
        UnboundSlot { pass: self.name.clone(), slot: format!("{slot:?}") }
    }
}
