//! Device memory shared between logical devices of one physical GPU: the staging area of a
//! `gpu` or `shared` link (links.rs). The producer allocates it exportable as an opaque fd and
//! each consumer imports it into its own `VkDevice`, so both copies of a cross-device transfer
//! run at memory speed on the GPU and no byte crosses the host.
//!
//! What the spec asks of an opaque-fd import, and how it is met:
//! * the importing buffer is created with the same `VkExternalMemoryBufferCreateInfo`, size
//!   and usage as the exporting one;
//! * `allocationSize` and `memoryTypeIndex` equal the exporter's
//!   (VUID-VkMemoryAllocateInfo-allocationSize-01742): one physical device lists the same memory
//!   types to every `VkDevice`, and the consumer's buffer must accept the exporter's type;
//! * a payload exported from a dedicated allocation must be imported as one: both sides always
//!   use `VkMemoryDedicatedAllocateInfo` (some drivers require it for export anyway);
//! * `vkGetMemoryFdPropertiesKHR` must not be called for opaque fds (its handle type may not be
//!   OPAQUE_FD): the memory type comes from the exporter instead;
//! * a successful import takes ownership of the fd; a failed one leaves it to us to close.

use std::os::fd::{FromRawFd, OwnedFd};
use std::sync::Arc;

use ash::vk;

use crate::device::Device;
use crate::device_support::SHARED_BUFFER_USAGE;
use crate::error::{BackendError, Result, VkContext};

const HANDLE: vk::ExternalMemoryHandleTypeFlags = vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD;

/// One `VkBuffer` bound to one allocation on one device.
struct View {
    device: Arc<Device>,
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
}

impl View {
    /// Frees the view; the device must no longer use it.
    fn free(self) {
        unsafe {
            self.device.raw.destroy_buffer(self.buffer, None);
            self.device.raw.free_memory(self.memory, None);
        }
    }
}

/// One device allocation seen by its producer and by its consumers as a `VkBuffer` each.
pub(crate) struct SharedDeviceBuffer {
    exporter: Option<View>,
    imports: Vec<View>,
    pub(crate) size: u64,
}

impl SharedDeviceBuffer {
    /// Allocates `size` bytes on `producer` (device-local where offered), zeroes them and
    /// imports them into every device of `consumers`.
    pub(crate) fn new(producer: &Arc<Device>, consumers: &[&Arc<Device>], size: u64) -> Result<Self> {
        let size = size.max(4);
        let buffer = create_buffer(producer, size)?;
        let requirements = unsafe { producer.raw.get_buffer_memory_requirements(buffer) };
        let memory_props = unsafe { producer.instance.raw.get_physical_device_memory_properties(producer.physical) };
        let memory_type = (0..memory_props.memory_type_count)
            .filter(|t| requirements.memory_type_bits & (1 << t) != 0)
            .min_by_key(|&t| {
                let flags = memory_props.memory_types[t as usize].property_flags;
                u32::from(!flags.contains(vk::MemoryPropertyFlags::DEVICE_LOCAL))
            });
        let Some(memory_type) = memory_type else {
            unsafe { producer.raw.destroy_buffer(buffer, None) };
            return Err(share_error(producer, format!("no memory type in bits {:#x}", requirements.memory_type_bits)));
        };
        let mut export = vk::ExportMemoryAllocateInfo::default().handle_types(HANDLE);
        let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().buffer(buffer);
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(requirements.size)
            .memory_type_index(memory_type)
            .push_next(&mut export)
            .push_next(&mut dedicated);
        let exporter = bind(producer, buffer, &alloc, "vkAllocateMemory(exportable)", || ())?;
        let mut shared = Self { exporter: Some(exporter), imports: Vec::with_capacity(consumers.len()), size };
        let (memory, buffer) = shared.exporter.as_ref().map(|e| (e.memory, e.buffer)).expect("just set");
        // Zeroed so that a copy-in that ran too early (a missing wait) reads zeros, never stale
        // bytes that could pass for a right answer.
        producer.one_shot(|cb| unsafe {
            producer.raw.cmd_fill_buffer(cb, buffer, 0, vk::WHOLE_SIZE, 0);
        })?;
        for consumer in consumers {
            let fd = export_fd(producer, memory)?;
            let view = import(consumer, fd, size, requirements.size, memory_type)?;
            shared.imports.push(view);
        }
        Ok(shared)
    }

    /// The `VkBuffer` through which device `device_index` sees the allocation.
    pub(crate) fn buffer_on(&self, device_index: usize) -> Option<vk::Buffer> {
        self.exporter.iter().chain(&self.imports).find(|v| v.device.info.index == device_index).map(|v| v.buffer)
    }
}

impl Drop for SharedDeviceBuffer {
    fn drop(&mut self) {
        // No device may still copy through the memory; the importers' views go before the
        // exporter's allocation, which owns the payload.
        for view in self.imports.iter().chain(&self.exporter) {
            let _ = unsafe { view.device.raw.device_wait_idle() };
        }
        self.imports.drain(..).for_each(View::free);
        if let Some(exporter) = self.exporter.take() {
            exporter.free();
        }
    }
}

fn share_error(device: &Device, detail: String) -> BackendError {
    BackendError::MemoryShare { device: device.info.index, detail }
}

/// A staging buffer of `size` bytes whose memory is (or will be) an opaque-fd payload.
fn create_buffer(device: &Device, size: u64) -> Result<vk::Buffer> {
    let mut external = vk::ExternalMemoryBufferCreateInfo::default().handle_types(HANDLE);
    let info = vk::BufferCreateInfo::default().size(size).usage(SHARED_BUFFER_USAGE).push_next(&mut external);
    let families = device.families();
    let info = if families.len() > 1 {
        info.sharing_mode(vk::SharingMode::CONCURRENT).queue_family_indices(&families)
    } else {
        info.sharing_mode(vk::SharingMode::EXCLUSIVE)
    };
    unsafe { device.raw.create_buffer(&info, None) }.vk("vkCreateBuffer(shared staging)")
}

/// Allocates with `alloc` (dedicated to `buffer`) and binds; on failure `buffer` is destroyed.
/// `allocated` runs as soon as the allocation exists.
fn bind(
    device: &Arc<Device>,
    buffer: vk::Buffer,
    alloc: &vk::MemoryAllocateInfo<'_>,
    call: &'static str,
    allocated: impl FnOnce(),
) -> Result<View> {
    let memory = match unsafe { device.raw.allocate_memory(alloc, None) } {
        Ok(memory) => {
            allocated();
            memory
        }
        Err(result) => {
            unsafe { device.raw.destroy_buffer(buffer, None) };
            return Err(BackendError::vk(call, result));
        }
    };
    let view = View { device: device.clone(), buffer, memory };
    if let Err(result) = unsafe { device.raw.bind_buffer_memory(buffer, memory, 0) } {
        view.free();
        return Err(BackendError::vk("vkBindBufferMemory(shared staging)", result));
    }
    Ok(view)
}

/// A new opaque fd of `memory`'s payload (each import consumes one).
fn export_fd(device: &Device, memory: vk::DeviceMemory) -> Result<OwnedFd> {
    let fns = device
        .external_memory_fd
        .as_ref()
        .ok_or_else(|| share_error(device, "VK_KHR_external_memory_fd is not enabled".into()))?;
    let info = vk::MemoryGetFdInfoKHR::default().memory(memory).handle_type(HANDLE);
    let fd = unsafe { fns.get_memory_fd(&info) }.vk("vkGetMemoryFdKHR")?;
    // SAFETY: vkGetMemoryFdKHR hands us a new fd that nothing else owns.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

/// Imports `fd` into `device` as a buffer of `size` bytes over `allocation_size` bytes of
/// `memory_type` (the exporter's).
fn import(device: &Arc<Device>, fd: OwnedFd, size: u64, allocation_size: u64, memory_type: u32) -> Result<View> {
    let buffer = create_buffer(device, size)?;
    let requirements = unsafe { device.raw.get_buffer_memory_requirements(buffer) };
    if requirements.memory_type_bits & (1 << memory_type) == 0 || requirements.size > allocation_size {
        unsafe { device.raw.destroy_buffer(buffer, None) };
        return Err(share_error(
            device,
            format!(
                "the exporter's memory type {memory_type} ({allocation_size} bytes) does not fit its buffer (bits {:#x}, {} bytes)",
                requirements.memory_type_bits, requirements.size
            ),
        ));
    }
    if device.external_memory_fd.is_none() {
        unsafe { device.raw.destroy_buffer(buffer, None) };
        return Err(share_error(device, "VK_KHR_external_memory_fd is not enabled".into()));
    }
    use std::os::fd::{AsRawFd, IntoRawFd};
    let mut import = vk::ImportMemoryFdInfoKHR::default().handle_type(HANDLE).fd(fd.as_raw_fd());

    let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().buffer(buffer);
    let alloc = vk::MemoryAllocateInfo::default()
        .allocation_size(allocation_size)
        .memory_type_index(memory_type)
        .push_next(&mut import)
        .push_next(&mut dedicated);
    // A successful import owns the fd; a failed one leaves it to `fd`'s drop to close.
    let mut fd = Some(fd);
    let owned_by_driver = || {
        let _ = fd.take().map(IntoRawFd::into_raw_fd);
    };
    bind(device, buffer, &alloc, "vkAllocateMemory(opaque fd import)", owned_by_driver)
}

/// `producer`'s exportable timeline `semaphore` imported into `consumer` (permanently): the
/// consumer's submissions can wait on it like on their own. An opaque fd of a semaphore, like
/// one of memory, belongs to the driver once imported.
pub(crate) fn import_timeline(producer: &Device, semaphore: vk::Semaphore, consumer: &Device) -> Result<vk::Semaphore> {
    let fns = |device: &Device| {
        device.external_semaphore_fd.clone().ok_or_else(|| BackendError::MissingCapability {
            device: device.info.index,
            name: device.info.name.clone(),
            what: "VK_KHR_external_semaphore_fd".into(),
        })
    };
    let info = vk::SemaphoreGetFdInfoKHR::default()
        .semaphore(semaphore)
        .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD);
    let fd = unsafe { fns(producer)?.get_semaphore_fd(&info) }.vk("vkGetSemaphoreFdKHR")?;
    // SAFETY: vkGetSemaphoreFdKHR hands us a new fd that nothing else owns.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    let imported = consumer.create_timeline(0)?;
    let import = vk::ImportSemaphoreFdInfoKHR::default()
        .semaphore(imported)
        .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD)
        .fd(std::os::fd::AsRawFd::as_raw_fd(&fd));
    match fns(consumer).and_then(|f| unsafe { f.import_semaphore_fd(&import) }.vk("vkImportSemaphoreFdKHR")) {
        Ok(()) => {
            let _ = std::os::fd::IntoRawFd::into_raw_fd(fd);
            Ok(imported)
        }
        Err(e) => {
            unsafe { consumer.raw.destroy_semaphore(imported, None) };
            Err(e)
        }
    }
}

#[cfg(test)]
mod tests {
    use gpu_allocator::MemoryLocation;

    use super::*;
    use crate::context::{Context, ContextDesc, DeviceSelection};
    use crate::instance::Validation;
    use crate::memory::Buffer;

    #[test]
    fn bytes_one_device_writes_into_shared_memory_are_what_another_device_of_the_gpu_reads() {
        let context =
            Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(2), validation: Validation::Core })
                .unwrap();
        let [producer, consumer] = [&context.devices[0], &context.devices[1]];
        let shared = SharedDeviceBuffer::new(producer, &[consumer], 256).unwrap();
        let on_producer = shared.buffer_on(0).unwrap();
        producer.one_shot(|cb| unsafe { producer.raw.cmd_fill_buffer(cb, on_producer, 64, 128, 0x1234_5678) }).unwrap();
        let read =
            Buffer::new(consumer, "read", 256, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu).unwrap();
        let on_consumer = shared.buffer_on(1).unwrap();
        let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: 256 };
        consumer.one_shot(|cb| unsafe { consumer.raw.cmd_copy_buffer(cb, on_consumer, read.raw, &[region]) }).unwrap();
        let words: Vec<u32> =
            read.mapped().unwrap().chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let expected: Vec<u32> = (0..64).map(|i| if (16..48).contains(&i) { 0x1234_5678 } else { 0 }).collect();
        assert_eq!(words, expected, "the fill on device 0, zeros elsewhere, seen by device 1");
        drop(shared);
        context.check_validation().unwrap();
    }
}
